//! Typed fixes: the change a refused request can make, named as data ([`Fix`]), and how each
//! front end spells it ([`spelled`]). A leaf module: the library's errors name their fixes
//! through it without depending on the error-kind table of [`crate::error`].

/// A change that can make a refused request work, named as data: the library's messages
/// write each [`Fix`] through [`std::fmt::Display`], which spells it in the terms of whoever
/// reads the message — by default the library's own (`LevelParams::rho`); the command line
/// and the Python module install their spelling (`--rho`, `rho=`) with [`spelled`] while
/// they format an error, so no front end rewrites message text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Fix {
    /// Accept a regularized answer to an undetermined global least squares (a ridge on the
    /// singular directions, or CGLS's minimum-norm answer).
    RegularizedAnswer,
    /// Accept a regularized answer to a rank-deficient global least squares, or the local
    /// inversion, which cuts the unsupported directions.
    RegularizeOrLocal,
    /// The relative singular-value cut-off of the pseudo-inverse.
    Cutoff,
    /// Fixed levels: the fine level `N` chosen by the caller.
    FixedLevels,
    /// Automatic levels, chosen from the samples.
    AutoLevels,
    /// The oversampling rate `rho = m / P` of the automatic levels.
    Rho,
    /// The 1D refiner's samples per leaf `rho`.
    RefineRho,
    /// The single-scale global least squares (banded normal equations, then the FWT).
    MethodSingleScale,
    /// The local inversion.
    MethodLocal,
    /// The global sparse least squares on the multilevel kernel matrix.
    MethodGlobal,
    /// The dense SVD pseudo-inverse.
    MethodDense,
    /// Column-pivoted QR for the local blocks.
    SolverQr,
    /// Drop non-finite samples and count them instead of refusing the set.
    DropNonfinite,
}

impl Fix {
    /// Every fix, so a front end can check that it spells each one.
    pub const ALL: [Fix; 13] = [
        Fix::RegularizedAnswer,
        Fix::RegularizeOrLocal,
        Fix::Cutoff,
        Fix::FixedLevels,
        Fix::AutoLevels,
        Fix::Rho,
        Fix::RefineRho,
        Fix::MethodSingleScale,
        Fix::MethodLocal,
        Fix::MethodGlobal,
        Fix::MethodDense,
        Fix::SolverQr,
        Fix::DropNonfinite,
    ];

    /// The fix in the library's terms: the parameter to set and its value.
    pub fn in_library(self) -> &'static str {
        match self {
            Fix::RegularizedAnswer => {
                "GlobalLsParams::rank_policy = RankPolicy::Regularize (ridge \
                 GlobalLsParams::ridge, e.g. 1e-10) or GlobalLsParams::method = \
                 GlobalMethod::Cgls"
            }
            Fix::RegularizeOrLocal => {
                "GlobalLsParams::rank_policy = RankPolicy::Regularize, or the local inversion"
            }
            Fix::Cutoff => "`cutoff` of LocalInversionParams or Method::Dense",
            Fix::FixedLevels => "Levels::Fixed { fine, .. }",
            Fix::AutoLevels => "Levels::Auto",
            Fix::Rho => "LevelParams::rho",
            Fix::RefineRho => "RefineParams::rho",
            Fix::MethodSingleScale => "Method::SingleScale",
            Fix::MethodLocal => "Method::Local",
            Fix::MethodGlobal => "Method::Global",
            Fix::MethodDense => "Method::Dense",
            Fix::SolverQr => "Solver::Qr",
            Fix::DropNonfinite => "NonFinitePolicy::Drop",
        }
    }
}

/// How a front end spells each [`Fix`] ([`Fix::in_library`] is the library's).
pub type Spelling = fn(Fix) -> &'static str;

thread_local! {
    /// The spelling [`Fix`]'s `Display` uses on this thread.
    static SPELLING: std::cell::Cell<Spelling> = const { std::cell::Cell::new(Fix::in_library) };
}

/// Runs `format` (typically `|| error.to_string()`) with every [`Fix`] written in
/// `spelling`, on this thread only; the previous spelling is restored afterwards, also when
/// `format` panics.
pub fn spelled<R>(spelling: Spelling, format: impl FnOnce() -> R) -> R {
    struct Restore(Spelling);
    impl Drop for Restore {
        fn drop(&mut self) {
            SPELLING.with(|s| s.set(self.0));
        }
    }
    let _restore = Restore(SPELLING.with(|s| s.replace(spelling)));
    format()
}

impl std::fmt::Display for Fix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(SPELLING.with(|s| s.get())(*self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn upper(fix: Fix) -> &'static str {
        match fix {
            Fix::Rho => "RHO",
            _ => "OTHER",
        }
    }

    /// A fix reads in the library's terms, in the spelling given inside [`spelled`], and in
    /// the library's terms again afterwards, also after a panic inside.
    #[test]
    fn spelling_is_scoped() {
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
        assert_eq!(spelled(upper, || Fix::Rho.to_string()), "RHO");
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
        let nested = spelled(upper, || {
            let inner = spelled(Fix::in_library, || Fix::Rho.to_string());
            (inner, Fix::Rho.to_string())
        });
        assert_eq!(nested, ("LevelParams::rho".to_string(), "RHO".to_string()));
        let panicked = std::panic::catch_unwind(|| spelled(upper, || panic!("inside")));
        assert!(panicked.is_err());
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
    }

    /// Errors that advise a fix write it through the spelling.
    #[test]
    fn errors_spell_their_fixes() {
        let e = crate::solve::SolveError::TooLarge {
            rows: 10,
            cols: 5,
            limit: 4,
        };
        let library = e.to_string();
        assert!(
            library.contains("Method::Global or Method::SingleScale"),
            "{library}"
        );
        let other = spelled(upper, || e.to_string());
        assert!(other.contains("(OTHER or OTHER)"), "{other}");
        for fix in Fix::ALL {
            assert!(!fix.in_library().is_empty());
        }
    }
}
