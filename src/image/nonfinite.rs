//! Non-finite radiance from a renderer: samples whose value is NaN or infinite in some channel.
//!
//! A sample `(x_i, y_i, f_i)` is *non-finite* when some channel `f_{i,c}` is NaN or `±Inf`
//! (its position must be finite: a position is what the caller asked for). Such a value has
//! no place in a least-squares fit or a pixel mean (one NaN poisons every coefficient whose
//! support holds it), so the samples are split before any fit: the finite ones become
//! [`ImageSamples`], the others are either refused ([`NonFinitePolicy::Refuse`], the default:
//! an error with their count and the first one's row, position and channel) or dropped and
//! counted ([`NonFinitePolicy::Drop`]: [`DroppedSamples`]).
//!
//! The dropped samples' positions are kept: the plan recognises its positions by an order-free
//! sum over all of them (`src/image/adaptive/protocol.rs`), and the sum over the kept samples
//! plus the sum over the dropped ones is the sum over all, so a round with dropped samples is
//! still recognised as the round the plan handed out.

use serde::Serialize;

use super::{ImageError, ImagePlane, ImageSamples};

/// What to do with samples whose value is NaN or infinite in some channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NonFinitePolicy {
    /// Refuse them all: an error with their count and the first one (the default: a renderer
    /// that emits NaN has a bug worth seeing).
    #[default]
    Refuse,
    /// Drop them and count them ([`DroppedSamples`]); the rest is fitted.
    Drop,
}

impl NonFinitePolicy {
    /// The policy of a front end's switch (`--drop-nonfinite`, `drop_nonfinite=True`):
    /// [`NonFinitePolicy::Drop`] when `drop`, else [`NonFinitePolicy::Refuse`].
    pub fn dropping(drop: bool) -> Self {
        if drop {
            NonFinitePolicy::Drop
        } else {
            NonFinitePolicy::Refuse
        }
    }
}

/// The first non-finite sample: where it is and what it holds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NonFiniteSample {
    /// Its 1-based row in the samples as given (the data row of a sample file).
    pub row: usize,
    /// Its x position (pixel units).
    pub x: f64,
    /// Its y position (pixel units).
    pub y: f64,
    /// The first channel (from 0) whose value is not finite.
    pub channel: usize,
    /// That value (NaN or an infinity).
    #[serde(serialize_with = "value_text")]
    pub value: f64,
}

/// JSON has no NaN or infinity: the value as text (`NaN`, `inf`, `-inf`).
fn value_text<S: serde::Serializer>(value: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&value.to_string())
}

/// The samples dropped under [`NonFinitePolicy::Drop`] (none under `Refuse`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DroppedSamples {
    /// How many samples were dropped.
    pub count: usize,
    /// The first of them (`None` when none was).
    pub first: Option<NonFiniteSample>,
    /// Their x positions (for the plan's recognition of its positions).
    #[serde(skip)]
    pub xs: Vec<f64>,
    /// Their y positions.
    #[serde(skip)]
    pub ys: Vec<f64>,
}

impl DroppedSamples {
    /// These dropped samples followed by `later` ones (the rows of `later` counted after
    /// `rows` kept and dropped samples before them): a plan's drops over its rounds.
    pub fn extend(&mut self, later: DroppedSamples, rows: usize) {
        if self.first.is_none() {
            self.first = later.first.map(|f| NonFiniteSample {
                row: f.row + rows,
                ..f
            });
        }
        self.count += later.count;
        self.xs.extend(later.xs);
        self.ys.extend(later.ys);
    }

    /// The report's note in words (`None` when nothing was dropped).
    pub fn note(&self) -> Option<String> {
        let first = self.first?;
        Some(format!(
            "{} samples with a non-finite value (NaN or Inf) were dropped; the first is row {} \
             at ({}, {}), channel {}: {}",
            self.count, first.row, first.x, first.y, first.channel, first.value
        ))
    }
}

/// Splits samples `(xs[i], ys[i], values[c][i])` on `plane` into the finite ones and the
/// non-finite ones under `policy` (module docs). The other checks are those of
/// [`ImageSamples::new`]; a non-finite position is refused whatever the policy.
pub fn split_finite(
    plane: ImagePlane,
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
    policy: NonFinitePolicy,
) -> Result<(ImageSamples, DroppedSamples), ImageError> {
    let lengths_agree = xs.len() == ys.len() && values.iter().all(|v| v.len() == xs.len());
    let bad: Vec<usize> = if lengths_agree {
        (0..xs.len())
            .filter(|&i| values.iter().any(|v| !v[i].is_finite()))
            .collect()
    } else {
        Vec::new() // ImageSamples::new names the length at fault
    };
    let Some(&i) = bad.first() else {
        return Ok((
            ImageSamples::new(plane, xs, ys, values)?,
            DroppedSamples::default(),
        ));
    };
    let channel = values
        .iter()
        .position(|v| !v[i].is_finite())
        .expect("a non-finite channel");
    let first = NonFiniteSample {
        row: i + 1,
        x: xs[i],
        y: ys[i],
        channel,
        value: values[channel][i],
    };
    if policy == NonFinitePolicy::Refuse {
        return Err(ImageError::NonFiniteSamples {
            count: bad.len(),
            row: first.row,
            x: first.x,
            y: first.y,
            channel,
            value: first.value,
        });
    }
    let keep = |v: &[f64]| -> Vec<f64> {
        let mut next = bad.iter().copied().peekable();
        v.iter()
            .enumerate()
            .filter(|&(j, _)| next.next_if_eq(&j).is_none())
            .map(|(_, &x)| x)
            .collect()
    };
    let dropped = DroppedSamples {
        count: bad.len(),
        first: Some(first),
        xs: bad.iter().map(|&j| xs[j]).collect(),
        ys: bad.iter().map(|&j| ys[j]).collect(),
    };
    let samples = ImageSamples::new(
        plane,
        keep(&xs),
        keep(&ys),
        values.iter().map(|v| keep(v)).collect(),
    )?;
    Ok((samples, dropped))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane() -> ImagePlane {
        ImagePlane::new(4, 4).unwrap()
    }

    /// Samples 2 and 4 (1-based rows 2 and 4) are non-finite, in channels 1 and 0.
    fn mixed() -> (Vec<f64>, Vec<f64>, Vec<Vec<f64>>) {
        let xs = vec![0.5, 1.5, 2.5, 3.5, 0.25];
        let ys = vec![0.5, 1.5, 2.5, 3.5, 3.75];
        let r = vec![1.0, 2.0, 3.0, f64::INFINITY, 5.0];
        let g = vec![1.0, f64::NAN, 3.0, 4.0, 5.0];
        (xs, ys, vec![r, g])
    }

    #[test]
    fn refuse_names_count_and_first() {
        let (xs, ys, v) = mixed();
        let e = split_finite(plane(), xs, ys, v, NonFinitePolicy::Refuse).unwrap_err();
        assert!(matches!(
            e,
            ImageError::NonFiniteSamples { count: 2, row: 2, channel: 1, x, y, .. }
                if x == 1.5 && y == 1.5
        ));
        let text = e.to_string();
        assert!(
            text.contains("2 samples") && text.contains("row 2"),
            "{text}"
        );
    }

    #[test]
    fn drop_keeps_the_finite_rows_in_order() {
        let (xs, ys, v) = mixed();
        let (s, d) = split_finite(plane(), xs, ys, v, NonFinitePolicy::Drop).unwrap();
        assert_eq!(s.xs(), &[0.5, 2.5, 0.25]);
        assert_eq!(s.channel(0), &[1.0, 3.0, 5.0]);
        assert_eq!(s.channel(1), &[1.0, 3.0, 5.0]);
        assert_eq!(
            (d.count, d.xs.clone(), d.ys.clone()),
            (2, vec![1.5, 3.5], vec![1.5, 3.5])
        );
        assert_eq!(d.first.map(|f| (f.row, f.channel)), Some((2, 1)));
        assert!(d.note().unwrap().contains("2 samples"));
    }

    #[test]
    fn finite_samples_pass_unchanged_under_both_policies() {
        let (xs, ys) = (vec![0.5, 1.5], vec![2.5, 3.5]);
        let v = vec![vec![1.0, 2.0]];
        for policy in [NonFinitePolicy::Refuse, NonFinitePolicy::Drop] {
            let (s, d) = split_finite(plane(), xs.clone(), ys.clone(), v.clone(), policy).unwrap();
            assert_eq!(
                s,
                ImageSamples::new(plane(), xs.clone(), ys.clone(), v.clone()).unwrap()
            );
            assert_eq!(d, DroppedSamples::default());
            assert!(d.note().is_none());
        }
    }

    #[test]
    fn dropping_every_sample_leaves_none_and_counts_them() {
        let v = vec![vec![f64::NAN]];
        let r = split_finite(plane(), vec![0.5], vec![0.5], v, NonFinitePolicy::Drop);
        assert!(r.is_ok_and(|(s, d)| s.is_empty() && d.count == 1));
    }
}
