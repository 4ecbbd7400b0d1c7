//! The rounds driver (`adaptive::rounds`) with a toy adapter, over random inputs: the stop
//! test gives the first reason that holds in the documented order (an independent list of
//! the conditions), the budget cut is the largest prefix that fits (a linear scan), and a
//! run of rounds never hands out more samples than the budget and stops for the exact reason.

use proptest::prelude::*;
use rkwave::adaptive::marking::{dorfler, within_budget};
use rkwave::adaptive::rounds::{cut, round, stop_test, RoundAdapter, RoundFacts};
use rkwave::adaptive::{StopParams, StopReason};

/// The reason a round stops, by an independent list of (condition, reason) in the order of
/// the module docs.
fn first_reason(f: &RoundFacts, s: &StopParams) -> Option<StopReason> {
    let conditions = [
        (f.estimate.is_none(), StopReason::Budget),
        (
            f.estimate
                .is_some_and(|e| e.is_finite() && e <= s.tolerance),
            StopReason::Tolerance,
        ),
        (!f.markable, StopReason::DepthLimit),
        (!f.resolvable, StopReason::Resolution),
        (f.spent, StopReason::Budget),
        (f.rounds >= s.max_rounds, StopReason::MaxRounds),
    ];
    conditions.into_iter().find(|c| c.0).map(|c| c.1)
}

fn facts() -> impl Strategy<Value = RoundFacts> {
    (
        prop_oneof![
            Just(None),
            Just(Some(f64::NAN)),
            Just(Some(f64::INFINITY)),
            (0.0..2.0f64).prop_map(Some)
        ],
        any::<[bool; 4]>(),
        0usize..8,
    )
        .prop_map(|(estimate, b, rounds)| RoundFacts {
            estimate,
            markable: b[0],
            deepenable: b[1],
            resolvable: b[2],
            spent: b[3],
            rounds,
        })
}

/// A toy dimension: units with indicators `eta` (descending) and additive sample costs; a
/// marked unit's detail is resolved (its `eta` drops by `decay`), a densifying round adds
/// `densify` samples, and the samples handed out are counted against the budget.
#[derive(Clone, Debug)]
struct Toy {
    eta: Vec<f64>,
    costs: Vec<usize>,
    decay: f64,
    samples: usize,
    budget: usize,
    theta: f64,
    rounds: usize,
    densify: usize,
    /// Nothing significant left (the round densifies) below this indicator.
    significant: f64,
    handed_out: Vec<usize>,
}

impl Toy {
    fn order(&mut self) {
        let mut idx: Vec<usize> = (0..self.eta.len()).collect();
        idx.sort_by(|&a, &b| self.eta[b].total_cmp(&self.eta[a]));
        self.eta = idx.iter().map(|&i| self.eta[i]).collect();
        self.costs = idx.iter().map(|&i| self.costs[i]).collect();
    }
    fn estimate(&self) -> f64 {
        self.eta.iter().map(|e| e * e).sum::<f64>().sqrt()
    }
}

impl RoundAdapter for Toy {
    type Marks = usize;
    type Outcome = Option<StopReason>;
    type Error = String;

    fn facts(&mut self) -> RoundFacts {
        self.order();
        let significant = self.eta.iter().any(|&e| e > self.significant);
        RoundFacts {
            estimate: Some(self.estimate()),
            markable: !self.eta.is_empty(),
            deepenable: significant,
            resolvable: true,
            spent: self.samples >= self.budget,
            rounds: self.rounds,
        }
    }
    fn stop(&mut self, reason: StopReason) -> Result<Self::Outcome, String> {
        Ok(Some(reason))
    }
    fn mark(&mut self) -> Result<Option<usize>, String> {
        let wanted = dorfler(&self.eta, self.theta);
        let remaining = self.budget - self.samples;
        let prefix = |k: usize| self.costs[..k].iter().sum::<usize>();
        let k = cut(wanted, remaining, prefix);
        Ok((k > 0).then_some(k))
    }
    fn deepen(&mut self, k: usize) -> Result<Self::Outcome, String> {
        let cost: usize = self.costs[..k].iter().sum();
        self.samples += cost;
        self.handed_out.push(cost);
        for e in &mut self.eta[..k] {
            *e *= self.decay;
        }
        self.rounds += 1;
        Ok(None)
    }
    fn densify(&mut self) -> Result<Option<Self::Outcome>, String> {
        let add = self.densify.min(self.budget - self.samples);
        if add == 0 {
            return Ok(None);
        }
        self.samples += add;
        self.handed_out.push(add);
        for e in &mut self.eta {
            *e *= 0.9;
        }
        self.rounds += 1;
        Ok(Some(None))
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The stop test is the first reason that holds, in the documented order.
    #[test]
    fn stop_test_gives_the_first_reason(
        f in facts(),
        tolerance in 0.0..1.5f64,
        max_rounds in 0usize..8,
    ) {
        let s = StopParams { tolerance, budget: 100, max_rounds };
        prop_assert_eq!(stop_test(&f, &s), first_reason(&f, &s));
    }

    /// The cut is the largest prefix of at most `wanted` units that fits, for any
    /// nondecreasing cost (a linear scan), and `within_budget` is the cut of prefix sums.
    #[test]
    fn cut_is_the_largest_prefix_that_fits(
        costs in prop::collection::vec(0usize..20, 0..40),
        remaining in 0usize..300,
        wanted_frac in 0.0..=1.0f64,
    ) {
        let wanted = (wanted_frac * costs.len() as f64).round() as usize;
        let prefix = |k: usize| costs[..k].iter().sum::<usize>();
        let scan = (0..=wanted).rev().find(|&k| prefix(k) <= remaining).unwrap_or(0);
        prop_assert_eq!(cut(wanted, remaining, prefix), scan);
        let all = (0..=costs.len()).rev().find(|&k| prefix(k) <= remaining).unwrap_or(0);
        prop_assert_eq!(within_budget(&costs, remaining), all);
    }

    /// Rounds of the toy until a stop: the samples handed out never exceed the budget, every
    /// round hands out samples, and the stop is the exact reason of the state it stopped in.
    #[test]
    fn rounds_keep_the_budget_and_stop_for_the_exact_reason(
        eta in prop::collection::vec(0.0..1.0f64, 1..30),
        costs in prop::collection::vec(1usize..12, 30),
        decay in 0.0..0.9f64,
        theta in 0.1..=1.0f64,
        budget in 0usize..200,
        base in 0usize..50,
        tolerance in 0.0..0.5f64,
        max_rounds in 1usize..40,
        significant in 0.0..0.3f64,
        densify in 1usize..10,
    ) {
        let costs = costs[..eta.len()].to_vec();
        let base = base.min(budget);
        let mut toy = Toy {
            eta, costs, decay, samples: base, budget, theta, rounds: 0, densify,
            significant, handed_out: Vec::new(),
        };
        let stop = StopParams { tolerance, budget, max_rounds };
        let reason = loop {
            let before = toy.clone();
            let outcome = round(&mut toy, &stop).unwrap();
            prop_assert!(toy.samples <= budget, "{} samples over the budget {budget}", toy.samples);
            match outcome {
                None => prop_assert!(toy.samples > before.samples, "a round that went on handed out nothing"),
                Some(reason) => {
                    // the round stopped without handing anything out
                    prop_assert_eq!(toy.samples, before.samples);
                    break (reason, before);
                }
            }
            prop_assert!(toy.rounds <= max_rounds, "past the round limit");
        };
        let (reason, mut state) = reason;
        let facts = state.facts();
        match first_reason(&facts, &stop) {
            Some(expected) => prop_assert_eq!(reason, expected),
            None => {
                // going on, the round could not pay for a mark (or a densifying round)
                prop_assert_eq!(reason, StopReason::Budget);
                let remaining = budget - state.samples;
                if facts.deepenable {
                    prop_assert!(state.costs[0] > remaining || dorfler(&state.eta, theta) == 0);
                } else {
                    prop_assert_eq!(remaining, 0);
                }
            }
        }
    }
}
