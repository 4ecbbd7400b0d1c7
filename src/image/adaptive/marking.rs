//! Dörfler marking on any list of indicators (the rule of the 1D refiner's
//! `Indication::dorfler`, here generic so the 2D refiner shares it rather than copies it).

/// Dörfler (bulk) marking: given indicators `eta` sorted in descending order, the fewest
/// leading ones whose squares hold at least `theta` of `sum eta^2`. Indicators `<= 0` are never
/// marked; an all-zero list marks nothing.
///
/// ```
/// use rkwave::image::adaptive::marking::dorfler;
/// assert_eq!(dorfler(&[3.0, 2.0, 1.0], 0.5), 1); // 9 >= 0.5 * 14
/// assert_eq!(dorfler(&[3.0, 2.0, 1.0], 0.9), 2); // 13 >= 12.6
/// assert_eq!(dorfler(&[0.0, 0.0], 0.5), 0);
/// ```
pub fn dorfler(eta: &[f64], theta: f64) -> usize {
    let total: f64 = eta.iter().map(|e| e * e).sum();
    if total <= 0.0 {
        return 0;
    }
    let mut acc = 0.0;
    for (i, &e) in eta.iter().enumerate() {
        if e <= 0.0 {
            return i;
        }
        acc += e * e;
        if acc >= theta * total {
            return i + 1;
        }
    }
    eta.len()
}

/// The longest prefix of `costs` whose sum fits in `budget`: how many of the marked units the
/// remaining samples pay for (the units are taken in indicator order, none skipped, so a
/// cheaper but less important unit never jumps the queue).
pub fn within_budget(costs: &[usize], budget: usize) -> usize {
    let mut spent = 0usize;
    for (i, &c) in costs.iter().enumerate() {
        spent = spent.saturating_add(c);
        if spent > budget {
            return i;
        }
    }
    costs.len()
}
