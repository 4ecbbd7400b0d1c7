//! Figures in words for the estimates' descriptions.

/// `a, b, c` with three significant digits.
pub(super) fn list(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:.3e}"))
        .collect::<Vec<_>>()
        .join(", ")
}
