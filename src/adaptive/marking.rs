//! Marking on any list of indicators, shared by the 1D and the 2D refiner: Dörfler's bulk
//! criterion (the fewest leading `eta_i`, sorted descending, with
//! `sum_{i<n} eta_i^2 >= theta sum_i eta_i^2`), the prefix a budget pays for, and the
//! spreading of a round's spare samples (2D).

/// Dörfler (bulk) marking: given indicators `eta` sorted in descending order, the fewest
/// leading ones whose squares hold at least `theta` of `sum eta^2`. Indicators `<= 0` are never
/// marked; an all-zero list marks nothing.
///
/// ```
/// use rkwave::adaptive::marking::dorfler;
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
/// cheaper but less important unit never jumps the queue). The rounds driver's budget cut
/// ([`super::rounds::cut`]) on additive costs, the prefix sums.
///
/// ```
/// use rkwave::adaptive::marking::within_budget;
/// assert_eq!(within_budget(&[4, 3, 5], 7), 2);
/// assert_eq!(within_budget(&[4, 3, 5], 3), 0);
/// ```
pub fn within_budget(costs: &[usize], budget: usize) -> usize {
    let mut prefix = Vec::with_capacity(costs.len() + 1);
    prefix.push(0usize);
    for &c in costs {
        prefix.push(prefix[prefix.len() - 1].saturating_add(c));
    }
    super::rounds::cut(costs.len(), budget, |k| prefix[k])
}

/// Where a round's spare samples go ([`spread`]): the samples left over when the marked slots
/// cost less than the round's least growth.
///
/// The two rules compared: docs/measurements/image-plane.md, "Variants tried at 64²".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpreadRule {
    /// Every slot alike: the lowest counts are raised first (a densifying round).
    Uniform,
    /// In proportion to each slot's indicator `eta` (insignificant slots and slots at the depth
    /// limit included): Neyman's allocation, the counts that minimise `sum eta_i^2 / n_i` for
    /// a given `sum n_i`, are `n_i ~ eta_i`.
    #[default]
    Indicator,
    /// The image refiner's rule (`image::adaptive`): a slot whose detail can still be
    /// deepened by its indicator `eta`; a slot whose detail does not decay (at the depth
    /// limit, or within the noise) by the uncertainty of its mean, `sqrt(A_i) s_i` (area in
    /// pixels, spread of its samples' residuals from the fit): Neyman's allocation for `sum A_i s_i^2 / n_i`, so
    /// samples go where the estimate is uncertain (noise, texture past the depth limit) and
    /// none to a constant slot.
    Uncertainty,
}

impl SpreadRule {
    /// Every rule.
    pub const ALL: [SpreadRule; 3] = [
        SpreadRule::Uniform,
        SpreadRule::Indicator,
        SpreadRule::Uncertainty,
    ];

    /// The name on the command line, in reports and in state files.
    pub fn name(self) -> &'static str {
        match self {
            SpreadRule::Uniform => "uniform",
            SpreadRule::Indicator => "indicator",
            SpreadRule::Uncertainty => "uncertainty",
        }
    }
}

impl std::str::FromStr for SpreadRule {
    type Err = String;
    /// A rule by [`SpreadRule::name`]; the error names the choices.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim().to_ascii_lowercase();
        SpreadRule::ALL
            .into_iter()
            .find(|r| r.name() == t)
            .ok_or_else(|| {
                format!("unknown spread rule `{s}`: expected uniform, indicator or uncertainty")
            })
    }
}

/// Spreads `extra` samples over slots holding `counts[i]` samples with weights `w[i] >= 0`:
/// the water level `lambda` with `sum_i max(0, lambda w_i - counts[i]) = extra` (bisection),
/// each slot raised to `floor(lambda w_i)`, the rest one by one to the slots furthest below
/// their level (ties by index). All-zero weights count as equal. Returns the samples added
/// per slot, summing to `extra` (none if there is no slot).
///
/// ```
/// use rkwave::adaptive::marking::spread;
/// assert_eq!(spread(&[1.0, 1.0, 1.0], &[2, 4, 2], 4), vec![2, 0, 2]); // water-filling
/// assert_eq!(spread(&[3.0, 1.0], &[0, 0], 8), vec![6, 2]); // n ~ w
/// assert_eq!(spread(&[0.0, 0.0], &[1, 1], 3).iter().sum::<usize>(), 3);
/// ```
pub fn spread(w: &[f64], counts: &[usize], extra: usize) -> Vec<usize> {
    let n = w.len();
    if n == 0 || extra == 0 {
        return vec![0; n];
    }
    let uniform = !w.iter().any(|&v| v > 0.0);
    let weight = |i: usize| if uniform { 1.0 } else { w[i].max(0.0) };
    let deficit = |lambda: f64, i: usize| (lambda * weight(i) - counts[i] as f64).max(0.0);
    let total = |lambda: f64| (0..n).map(|i| deficit(lambda, i)).sum::<f64>();
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while total(hi) < extra as f64 {
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if total(mid) <= extra as f64 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let mut add: Vec<usize> = (0..n).map(|i| deficit(lo, i).floor() as usize).collect();
    let mut left = extra.saturating_sub(add.iter().sum());
    // the rest to the slots furthest below the level `hi` (ties by index)
    let mut order: Vec<usize> = (0..n).filter(|&i| weight(i) > 0.0).collect();
    order.sort_by(|&a, &b| {
        let da = hi * weight(a) - (counts[a] + add[a]) as f64;
        let db = hi * weight(b) - (counts[b] + add[b]) as f64;
        db.total_cmp(&da).then(a.cmp(&b))
    });
    while left > 0 {
        for &i in &order {
            if left == 0 {
                break;
            }
            add[i] += 1;
            left -= 1;
        }
    }
    add
}
