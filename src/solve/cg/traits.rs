//! What a conjugate-gradient run iterates with: the symmetric positive (semi)definite
//! operator `A` and the preconditioner `M^{-1}`.

/// A symmetric positive (semi)definite operator `A`, applied to several vectors at once.
pub trait SymmetricOperator: Sync {
    /// Unknowns `n` (the length of every vector).
    fn dim(&self) -> usize;
    /// `q_c = A p_c` for every `c` (`q[c]` is overwritten or replaced by a vector of length
    /// [`Self::dim`]).
    fn apply(&self, p: &[&[f64]], q: &mut [Vec<f64>]);
}

/// A preconditioner `M^{-1} ≈ A^{-1}` (symmetric positive definite on the range of `A`),
/// applied to several vectors at once.
pub trait Preconditioner: Sync {
    /// `z_c = M^{-1} r_c` for every `c` (`z[c]`, of the length of `r[c]`, overwritten).
    fn apply(&self, r: &[&[f64]], z: &mut [Vec<f64>]);
}
