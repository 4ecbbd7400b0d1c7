//! A round given only its new samples: the samples a plan has read ([`ReadSamples`]), the
//! refusal of "new" samples that are not the round handed out
//! ([`PlanState::check_new_round`]), and their join with the earlier ones.
//!
//! *Which round.* The plan's record of the positions it handed out holds the cumulative
//! fingerprint `F_r = sum_{i in rounds 0..=r} h(x_i, y_i) mod 2^64` and the count of each
//! round (module docs of [`super`]). The positions of round `r` alone have the fingerprint
//! `F_r - F_{r-1} mod 2^64` (`F_{-1} = 0`; the sum is a group sum, so the difference is exact)
//! and the count `positions_r`. A round given only its new samples must match the last round
//! handed out that way (kept and dropped positions together, as the cumulative check); a
//! match with an earlier round's difference is a repeated round, a match with a cumulative
//! `F_j` is every sample so far given as new, another count is the wrong count, and the same
//! count with another fingerprint is positions moved (another run, rounded to float32). Each
//! refusal names the round and count expected.
//!
//! *The join.* The samples the call fits are the earlier ones in the order read followed by
//! the new ones in the order given ([`ReadSamples::joined`]): the samples a caller giving
//! every sample so far as that concatenation would pass, so the round is the same bit for
//! bit (positions, fits, final image).
//!
//! *Bytes.* A plan kept in files holds the samples it has read beside its state
//! (`io::plan_files`, `samples.bin`): a sequence of pieces, each the rows added by one call
//! ([`ReadSamples::piece_bytes`]: the sealed layout of the caches, tagged with the plan and
//! checksummed, preceded by its length), appended per call. Unlike the caches it is not
//! optional for a call given only its new samples: without it the earlier samples are
//! unknown, and the call is refused, naming the fix (give every sample so far).

use super::{fingerprint, parse_hex, PlanState, ProtocolError};
use crate::image::adaptive::gram::{seal, unseal, GramBytesError, Words};
use crate::image::nonfinite::NonFiniteSample;
use crate::image::{DroppedSamples, ImagePlane, ImageSamples};

/// The first bytes of a piece of [`ReadSamples::piece_bytes`]: the layout's name and version.
const PIECE_MAGIC: &[u8; 8] = b"RKWSMP01";

/// The samples of the rounds a plan has read, in the order read (module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReadSamples {
    /// The last round whose samples these are (`None`: no round read).
    pub through: Option<usize>,
    /// The finite samples (`None`: none read).
    pub samples: Option<ImageSamples>,
    /// The samples dropped for a non-finite value (their positions count in the rounds).
    pub dropped: DroppedSamples,
}

impl ReadSamples {
    /// Rows read: finite and dropped samples.
    pub fn rows(&self) -> usize {
        self.samples.as_ref().map_or(0, ImageSamples::len) + self.dropped.xs.len()
    }

    /// The earlier samples followed by `new` (the rows `new_dropped` dropped from them,
    /// counted after these rows): the samples of every round so far (module docs). The
    /// earlier samples are moved, not copied.
    pub fn joined(
        self,
        new: ImageSamples,
        new_dropped: DroppedSamples,
    ) -> Result<(ImageSamples, DroppedSamples), ProtocolError> {
        let rows = self.rows();
        let mut dropped = self.dropped;
        dropped.extend(new_dropped, rows);
        let all = match self.samples {
            None => new,
            Some(old) => append_owned(old, &new)?,
        };
        Ok((all, dropped))
    }

    /// Whether these samples are the first ones of `all` and `all_dropped` in the same
    /// order, by their bits (then `all` continues them).
    pub fn starts(&self, all: &ImageSamples, all_dropped: &DroppedSamples) -> bool {
        let same = |a: &[f64], b: &[f64]| {
            a.len() <= b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
        };
        let (d, ad) = (&self.dropped, all_dropped);
        let dropped = same(&d.xs, &ad.xs)
            && same(&d.ys, &ad.ys)
            && (d.first.is_none() || d.first == ad.first);
        let kept = match &self.samples {
            None => true,
            Some(s) => {
                s.channels() == all.channels()
                    && same(s.xs(), all.xs())
                    && same(s.ys(), all.ys())
                    && s.values().iter().zip(all.values()).all(|(a, b)| same(a, b))
            }
        };
        dropped && kept
    }

    /// The rows of these samples from the `kept` finite and `dropped` dropped ones on, as one
    /// piece of the plan's file (module docs; `seal`: `RKWSMP01`, the plan's `tag`, the
    /// round `through` they complete, the counts, the channels, the first dropped sample if it
    /// lies in the piece, then the positions, each channel's values and the dropped
    /// positions by their bits; a checksum), preceded by the piece's length in bytes.
    pub fn piece_bytes(
        &self,
        tag: u64,
        through: usize,
        (kept, dropped): (usize, usize),
    ) -> Vec<u8> {
        let tail = |v: &[f64], from: usize| v[from.min(v.len())..].to_vec();
        let (xs, ys, values) = match &self.samples {
            Some(s) => (
                tail(s.xs(), kept),
                tail(s.ys(), kept),
                s.values().iter().map(|v| tail(v, kept)).collect(),
            ),
            None => (Vec::new(), Vec::new(), Vec::new()),
        };
        let (dxs, dys) = (
            tail(&self.dropped.xs, dropped),
            tail(&self.dropped.ys, dropped),
        );
        let first = self.dropped.first.filter(|f| f.row > kept + dropped);
        let channels = values.len();
        let words = 10 + xs.len() * (2 + channels) + 2 * dxs.len();
        let sealed = seal(PIECE_MAGIC, tag, words, |word| {
            word(through as u64);
            word(xs.len() as u64);
            word(dxs.len() as u64);
            word(channels as u64);
            word(u64::from(first.is_some()));
            let f = first.unwrap_or(NonFiniteSample {
                row: 0,
                x: 0.0,
                y: 0.0,
                channel: 0,
                value: 0.0,
            });
            word(f.row as u64);
            word(f.x.to_bits());
            word(f.y.to_bits());
            word(f.channel as u64);
            word(f.value.to_bits());
            let columns = [&xs, &ys].into_iter().chain(&values).chain([&dxs, &dys]);
            columns.flatten().for_each(|v| word(v.to_bits()));
        });
        let mut out = (sealed.len() as u64).to_le_bytes().to_vec();
        out.extend(sealed);
        out
    }

    /// The samples of the plan's file `bytes` (pieces of [`ReadSamples::piece_bytes`] for the
    /// plan tagged `tag`, on `plane`) through round `through`, checked against the positions
    /// `state` handed out: after each piece, the rows read must be the positions of rounds
    /// `0..=r` of its round `r` (count and fingerprint). Pieces after the one completing
    /// `through` (a later call's, of a state since replaced) are left out. Also the length
    /// of the bytes used (a later piece is appended there).
    pub fn from_bytes(
        bytes: &[u8],
        tag: u64,
        plane: ImagePlane,
        state: &PlanState,
        through: usize,
    ) -> Result<(ReadSamples, usize), String> {
        let mut read = ReadSamples::default();
        let mut at = 0usize;
        // the fingerprint of the rows read so far, continued piece by piece (a sum)
        let mut f = 0u64;
        while read.through != Some(through) {
            let Some(len) = bytes.get(at..at + 8) else {
                return Err(match read.through {
                    None => "it holds no samples".into(),
                    Some(r) => format!(
                        "it holds the samples of rounds 0..={r}, the plan has read rounds \
                         0..={through}"
                    ),
                });
            };
            let len = u64::from_le_bytes(len.try_into().expect("8 bytes")) as usize;
            let piece = bytes
                .get(at + 8..(at + 8).saturating_add(len))
                .ok_or("damaged: cut short")?;
            at += 8 + len;
            let words = unseal(piece, PIECE_MAGIC, "plan's samples", tag)
                .map_err(|e: GramBytesError| e.to_string())?;
            let (round, piece) = read_piece(words, plane).map_err(|e| e.to_string())?;
            if read.through.is_some_and(|r| round <= r) || round > through {
                return Err(format!("damaged: a piece of round {round} out of order"));
            }
            if let Some(s) = &piece.samples {
                f = fingerprint(f, s.xs(), s.ys());
            }
            f = fingerprint(f, &piece.dropped.xs, &piece.dropped.ys);
            read.extend(piece)?;
            read.through = Some(round);
            let issued = &state.issued[round];
            if read.rows() != issued.total || parse_hex(&issued.fingerprint) != Some(f) {
                return Err(format!(
                    "its samples of rounds 0..={round} ({} rows) are not the positions this \
                     plan handed out for them ({}); it belongs to another state of the plan",
                    read.rows(),
                    issued.total
                ));
            }
        }
        Ok((read, at))
    }

    /// These samples followed by the rows of `piece` (its first dropped sample's row is the
    /// row in every sample so far).
    fn extend(&mut self, piece: ReadSamples) -> Result<(), String> {
        let first = self.dropped.first.or(piece.dropped.first);
        self.dropped.extend(piece.dropped, 0);
        self.dropped.first = first;
        let Some(new) = piece.samples else {
            return Ok(());
        };
        self.samples = Some(match self.samples.take() {
            None => new,
            Some(old) => append_owned(old, &new).map_err(|e| format!("damaged: {e}"))?,
        });
        Ok(())
    }
}

/// `old` followed by `new`, in that order (the same plane and channels, else refused): the
/// samples of every round so far, as every front end joins a round's new samples.
pub fn appended(
    old: Option<&ImageSamples>,
    new: ImageSamples,
) -> Result<ImageSamples, ProtocolError> {
    match old {
        None => Ok(new),
        Some(old) => append_owned(old.clone(), &new),
    }
}

/// `old` followed by `new` ([`appended`]), `old`'s vectors extended in place.
fn append_owned(old: ImageSamples, new: &ImageSamples) -> Result<ImageSamples, ProtocolError> {
    let plane = old.plane();
    if plane != new.plane() {
        return Err(ProtocolError::Plane {
            state: plane,
            given: new.plane(),
        });
    }
    if old.channels() != new.channels() {
        return Err(ProtocolError::Channels {
            state: old.channels(),
            given: new.channels(),
        });
    }
    let (mut xs, mut ys, mut values) = old.into_parts();
    xs.extend_from_slice(new.xs());
    ys.extend_from_slice(new.ys());
    for (v, n) in values.iter_mut().zip(new.values()) {
        v.extend_from_slice(n);
    }
    // both validated on the same plane with the same channels: nothing to refuse
    Ok(ImageSamples::new(plane, xs, ys, values)
        .expect("two validated sample sets on one plane join"))
}

/// One piece's round and rows (the words after the tag of [`ReadSamples::piece_bytes`]).
fn read_piece(
    mut words: Words<'_>,
    plane: ImagePlane,
) -> Result<(usize, ReadSamples), GramBytesError> {
    let head = words.take(10)?;
    let [round, kept, dropped, channels, has_first, row, x, y, channel, value] = head[..] else {
        return Err(GramBytesError::Damaged("cut short"));
    };
    let (kept, dropped, channels) = (kept as usize, dropped as usize, channels as usize);
    let expected = kept as u128 * (2 + channels as u128) + 2 * dropped as u128;
    if words.left() as u128 != expected {
        return Err(GramBytesError::Damaged("the sizes do not add up"));
    }
    let mut column = |n: usize| -> Result<Vec<f64>, GramBytesError> {
        Ok(words.take(n)?.into_iter().map(f64::from_bits).collect())
    };
    let xs = column(kept)?;
    let ys = column(kept)?;
    let values = (0..channels)
        .map(|_| column(kept))
        .collect::<Result<Vec<_>, _>>()?;
    let (dxs, dys) = (column(dropped)?, column(dropped)?);
    let samples = match channels {
        0 => None,
        _ => Some(
            ImageSamples::new(plane, xs, ys, values)
                .map_err(|_| GramBytesError::Damaged("samples off the plane or not finite"))?,
        ),
    };
    let first = (has_first == 1).then_some(NonFiniteSample {
        row: row as usize,
        x: f64::from_bits(x),
        y: f64::from_bits(y),
        channel: channel as usize,
        value: f64::from_bits(value),
    });
    Ok((
        round as usize,
        ReadSamples {
            through: Some(round as usize),
            samples,
            dropped: DroppedSamples {
                count: dropped,
                first,
                xs: dxs,
                ys: dys,
            },
        },
    ))
}

impl PlanState {
    /// Refuses `new` (with `dropped`, the positions of its non-finite samples) unless they
    /// are the positions of the last round handed out, alone (module docs): a repeated
    /// round, every sample so far, a wrong count and moved positions are each refused,
    /// naming the round and the count expected. The rows read so far (`earlier`, finite and
    /// dropped) must be those of every earlier round.
    pub fn check_new_round(
        &self,
        earlier: usize,
        new: &ImageSamples,
        dropped: &DroppedSamples,
    ) -> Result<(), ProtocolError> {
        if new.plane() != self.plane {
            return Err(ProtocolError::Plane {
                state: self.plane,
                given: new.plane(),
            });
        }
        if let Some(c) = self.channels.filter(|&c| c != new.channels()) {
            return Err(ProtocolError::Channels {
                state: c,
                given: new.channels(),
            });
        }
        let last = self.issued.len() - 1;
        if self.stop.is_some() {
            return Err(ProtocolError::NoRoundPending { round: last });
        }
        let before = last.checked_sub(1).map_or(0, |r| self.issued[r].total);
        if earlier != before {
            return Err(ProtocolError::EarlierUnknown {
                held: earlier,
                expected: before,
                round: last,
            });
        }
        let given = new.len() + dropped.xs.len();
        let f = fingerprint(fingerprint(0, new.xs(), new.ys()), &dropped.xs, &dropped.ys);
        let cumulative = |r: usize| parse_hex(&self.issued[r].fingerprint).unwrap_or(0);
        let round_alone = |r: usize| {
            let before = r.checked_sub(1).map_or(0, cumulative);
            (self.issued[r].positions, cumulative(r).wrapping_sub(before))
        };
        let expected = self.issued[last].positions;
        if round_alone(last) == (given, f) {
            return Ok(());
        }
        if let Some(r) = (0..last).find(|&r| round_alone(r) == (given, f)) {
            return Err(ProtocolError::NewRoundRepeated {
                given,
                matched: r,
                round: last,
                expected,
            });
        }
        if let Some(r) = (1..=last).find(|&r| (self.issued[r].total, cumulative(r)) == (given, f)) {
            return Err(ProtocolError::NewRoundCumulative {
                given,
                matched: r,
                round: last,
                expected,
            });
        }
        if given != expected {
            return Err(ProtocolError::NewRoundCount {
                given,
                round: last,
                expected,
            });
        }
        Err(ProtocolError::NewRoundMoved { given, round: last })
    }
}
