//! A band's tile states held where its tasks run (issue 40, item 4): the banded round of
//! [`super::band`] without sending the tiles' states to the band's task and back every round.
//!
//! A tile's state is its record (index, parameters, last indicator `eta_t^2`, stop, steps:
//! what the round's shares, stops and memory checks read on the client) and two parts that
//! grow with its tree: its refinement history and PCG's start. [`BandTask`] carries the whole
//! state of every stepped tile to the task and [`super::BandOutcome`] brings it back (8 to 15
//! MB a round each way at 256², more than the round's new samples). Here:
//!
//! - the process that steps a band keeps the band's states, [`HeldBand`] (every tile of the
//!   band in tile order, whole), named by its digest `d = D(json(HeldBand))`
//!   ([`HeldBand::digest`]: 64 bits of the serialised states, so any changed bit of any tile
//!   changes it but for a chance of about `2^-64`);
//! - the client keeps each tile's record alone ([`tile_record`]: the history and the start
//!   dropped) and each held band's digest ([`HeldBands`]);
//! - a round's task, [`HeldBandTask`], is the band task on the records with the digest of the
//!   held states it must step; [`HeldBandTask::run`] refuses other states (another band's, an
//!   earlier round's), steps the tiles with a share with [`BandTask::run`] on their whole
//!   states, and gives the outcome with the new states' records and both digests
//!   ([`HeldBandOutcome`]) beside the new [`HeldBand`], which stays;
//! - [`TiledPlanState::commit_held_round`] refuses an outcome stepped from other states than
//!   the round's (then [`TiledPlanState::commit_round`]'s refusals: missing, repeated, of
//!   another round) and records the new digests.
//!
//! **Same bits.** The step is [`BandTask::run`] on the whole states the local round would
//! hold (the held ones, checked by their digest), so the new states and positions are the
//! local round's, bit for bit; the client's records are those states without the two parts
//! no client-side function reads.
//!
//! **Recovery.** A band's held states are a function of its initial states and the tasks of
//! the rounds that stepped it with each round's samples: the initial states are the records
//! with the history, start, indicator, stop and steps reset ([`TiledPlanState::initial_band`]:
//! a tile's parameters never change after the plan's start), and each round's samples are a
//! prefix of the band's samples (they grow only at their end). A client that keeps every
//! round's task of a band (its records, shares and digest: a few hundred bytes a tile and
//! round) and the round's count of the band's samples can replay a lost band: each replayed
//! task checks the states it is given by their digest, so a replay that differed by one bit
//! would be refused, not committed.
//!
//! The final image: [`HeldFinalBandTask`] is [`FinalBandTask`] on the records with the held
//! band's digest; its run fits the held whole states. [`TiledPlanState::with_held`] splices
//! held bands into a copy of the client's state (to write it whole).

use std::ops::Range;

use serde::{Deserialize, Serialize};

use super::band::{BandError, BandOutcome, BandStrip, BandTask, FinalBandTask, RoundPlan};
use super::state::{TilePlanState, TiledPlanState};
use super::stops::TiledStep;
use crate::image::adaptive::{mix64, PlanProgress};
use crate::image::ImageSamples;

/// A tile's record on the client: its state without the refinement history and PCG's start
/// (module docs).
pub fn tile_record(state: &TilePlanState) -> TilePlanState {
    TilePlanState {
        progress: PlanProgress::default(),
        start: None,
        ..state.clone()
    }
}

/// The whole states of a band's tiles, held by the process that steps the band (module docs),
/// with their digest (computed once: the band does not change after it is made).
#[derive(Clone, Debug, PartialEq)]
pub struct HeldBand {
    rows: Range<usize>,
    tiles: Vec<TilePlanState>,
    digest: u64,
}

/// [`HeldBand`] as serialised: its rows and tiles (the digest is computed again when read).
#[derive(Serialize)]
struct HeldBandRef<'a> {
    rows: &'a Range<usize>,
    tiles: &'a [TilePlanState],
}

#[derive(Deserialize)]
struct HeldBandFile {
    rows: Range<usize>,
    tiles: Vec<TilePlanState>,
}

impl Serialize for HeldBand {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        HeldBandRef {
            rows: &self.rows,
            tiles: &self.tiles,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for HeldBand {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let f = HeldBandFile::deserialize(d)?;
        Ok(HeldBand::new(f.rows, f.tiles))
    }
}

impl HeldBand {
    /// The band of tile rows `rows` with its tiles' whole states `tiles` (in tile order).
    pub fn new(rows: Range<usize>, tiles: Vec<TilePlanState>) -> Self {
        let bytes = serde_json::to_vec(&HeldBandRef {
            rows: &rows,
            tiles: &tiles,
        })
        .expect("a band's states serialise");
        let mut chunks = bytes.chunks_exact(8);
        let mut h = mix64(bytes.len() as u64);
        for c in &mut chunks {
            h = mix64(h ^ u64::from_le_bytes(c.try_into().expect("8 bytes")));
        }
        let mut last = [0u8; 8];
        last[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
        let digest = mix64(h ^ u64::from_le_bytes(last));
        HeldBand {
            rows,
            tiles,
            digest,
        }
    }

    /// The digest `D(json(band))`: the serialised band folded 8 bytes at a time,
    /// `h <- mix64(h ^ w)` from the byte count (module docs).
    pub fn digest(&self) -> u64 {
        self.digest
    }

    /// The band's tile rows `[r0, r1)`.
    pub fn rows(&self) -> &Range<usize> {
        &self.rows
    }

    /// The band's tiles' whole states, in tile order.
    pub fn tiles(&self) -> &[TilePlanState] {
        &self.tiles
    }

    /// The whole state of tile `index`, if it is the band's.
    fn tile(&self, index: usize) -> Option<&TilePlanState> {
        self.tiles.iter().find(|t| t.index == index)
    }

    /// `records` (the client's records of some of the band's tiles) replaced by the held
    /// whole states, each checked to be the state the record was taken from.
    fn whole(
        &self,
        records: &[TilePlanState],
        what: &'static str,
    ) -> Result<Vec<TilePlanState>, BandError> {
        records
            .iter()
            .map(|r| match self.tile(r.index) {
                Some(t) if tile_record(t) == *r => Ok(t.clone()),
                _ => Err(BandError::Foreign {
                    what,
                    problem: format!(
                        "tile {}'s held state is not the one the client recorded (held tiles \
                         {:?} of tile rows {:?}): give the band's held states of this round",
                        r.index,
                        self.tiles.iter().map(|t| t.index).collect::<Vec<_>>(),
                        self.rows
                    ),
                }),
            })
            .collect()
    }

    /// Refuses a band whose rows or digest are not the task's.
    fn check(&self, rows: &Range<usize>, digest: u64, what: &'static str) -> Result<(), BandError> {
        let held = self.digest();
        if self.rows != *rows || held != digest {
            return Err(BandError::Foreign {
                what,
                problem: format!(
                    "the held states of tile rows {:?} (digest {held:016x}) are given to the \
                     task of tile rows {rows:?} stepping digest {digest:016x}: give the band's \
                     held states of this round (or replay the band from its initial states)",
                    self.rows
                ),
            });
        }
        Ok(())
    }
}

/// A band's task of a round when its states are held (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldBandTask {
    /// The band task with the stepped tiles' records ([`tile_record`]).
    pub band: BandTask,
    /// The digest of the held states it steps.
    pub held: u64,
}

/// What a held band's task returns to the client (its new states stay where it ran).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldBandOutcome {
    /// The band's outcome, the tiles' new states as their records.
    pub outcome: BandOutcome,
    /// The digest of the states it stepped.
    pub from: u64,
    /// The digest of the new states.
    pub to: u64,
}

impl HeldBandTask {
    /// The task of `band` (as [`TiledPlanState::begin_round`] made it) on the held states of
    /// digest `held`: its tiles reduced to their records.
    pub fn new(mut band: BandTask, held: u64) -> Self {
        band.tiles = band.tiles.iter().map(tile_record).collect();
        HeldBandTask { band, held }
    }

    /// The band's step on its held states (module docs): refused unless `held` is the band's
    /// states of digest `self.held` and their records are the task's; the outcome and the
    /// band's new states.
    pub fn run(
        &self,
        held: &HeldBand,
        samples: &ImageSamples,
    ) -> Result<(HeldBandOutcome, HeldBand), BandError> {
        held.check(&self.band.rows, self.held, "a band's held states")?;
        let mut task = self.band.clone();
        task.tiles = held.whole(&self.band.tiles, "a band's held states")?;
        let mut outcome = task.run(samples)?;
        let mut tiles = held.tiles.clone();
        for o in &mut outcome.tiles {
            let record = tile_record(&o.state);
            let whole = std::mem::replace(&mut o.state, record);
            let slot = tiles
                .iter_mut()
                .find(|t| t.index == whole.index)
                .expect("a stepped tile is one of the band's (checked above)");
            *slot = whole;
        }
        let next = HeldBand::new(held.rows.clone(), tiles);
        let to = next.digest();
        let outcome = HeldBandOutcome {
            outcome,
            from: self.held,
            to,
        };
        Ok((outcome, next))
    }
}

/// The final image's task of a band whose states are held (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldFinalBandTask {
    /// The final band task with the band's tiles' records.
    pub task: FinalBandTask,
    /// The digest of the held states it fits.
    pub held: u64,
}

impl HeldFinalBandTask {
    /// The task of `task` (as [`TiledPlanState::final_bands`] made it) on the held states of
    /// digest `held`.
    pub fn new(mut task: FinalBandTask, held: u64) -> Self {
        task.band.tiles = task.band.tiles.iter().map(tile_record).collect();
        HeldFinalBandTask { task, held }
    }

    /// The band's strip of the final image from its held states (refused as
    /// [`HeldBandTask::run`] refuses).
    pub fn run(&self, held: &HeldBand, samples: &ImageSamples) -> Result<BandStrip, BandError> {
        let what = "a band's held states (final image)";
        held.check(&self.task.band.rows, self.held, what)?;
        let mut task = self.task.clone();
        task.band.tiles = held.whole(&self.task.band.tiles, what)?;
        task.run(samples)
    }
}

/// The client's digests of the bands whose states are held elsewhere, by their first tile
/// row (module docs). A band without one has its whole states in the client's state.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeldBands {
    digests: std::collections::BTreeMap<usize, (Range<usize>, u64)>,
}

impl HeldBands {
    /// The digest of the held states of band `rows` (`None`: the client's state has them).
    pub fn get(&self, rows: &Range<usize>) -> Option<u64> {
        self.digests
            .get(&rows.start)
            .filter(|(r, _)| r == rows)
            .map(|&(_, d)| d)
    }

    /// Bands held, with their digests.
    pub fn iter(&self) -> impl Iterator<Item = (&Range<usize>, u64)> {
        self.digests.values().map(|(r, d)| (r, *d))
    }

    /// Bands held.
    pub fn len(&self) -> usize {
        self.digests.len()
    }

    /// Whether no band is held.
    pub fn is_empty(&self) -> bool {
        self.digests.is_empty()
    }
}

impl TiledPlanState {
    /// The band `rows`' tiles' states as the client holds them (whole for a band never
    /// held; see [`HeldBands`]).
    pub fn held_band(&self, rows: Range<usize>) -> HeldBand {
        let nx = self.geometry().grid().0;
        let tiles = self.tiles[rows.start * nx..rows.end * nx].to_vec();
        HeldBand::new(rows, tiles)
    }

    /// The band `rows`' states at the plan's start, from the client's records (module docs:
    /// the start of a replay).
    pub fn initial_band(&self, rows: Range<usize>) -> HeldBand {
        let nx = self.geometry().grid().0;
        let tiles = self.tiles[rows.start * nx..rows.end * nx]
            .iter()
            .map(|t| TilePlanState {
                index: t.index,
                params: t.params,
                progress: PlanProgress::default(),
                start: None,
                indicator_sq: None,
                stop: None,
                steps: 0,
            })
            .collect();
        HeldBand::new(rows, tiles)
    }

    /// The digest of band `rows`' states: the held one, else that of the client's own.
    pub fn band_digest(&self, held: &HeldBands, rows: &Range<usize>) -> u64 {
        held.get(rows)
            .unwrap_or_else(|| self.held_band(rows.clone()).digest())
    }

    /// The tasks of a begun round on held states: each band task of `plan` (taken out of it)
    /// with its band's digest, and its samples.
    pub fn held_tasks(
        &self,
        plan: &mut RoundPlan,
        held: &HeldBands,
    ) -> Vec<(HeldBandTask, ImageSamples)> {
        std::mem::take(&mut plan.tasks)
            .into_iter()
            .map(|(t, s)| {
                let d = self.band_digest(held, &t.rows);
                (HeldBandTask::new(t, d), s)
            })
            .collect()
    }

    /// [`TiledPlanState::commit_round`] of held bands' outcomes: refused, the state and
    /// `held` unchanged, when an outcome stepped other states than the band's recorded ones
    /// (`held`, else the client's own), then as `commit_round` refuses; else the step, and
    /// `held` records the bands' new digests.
    pub fn commit_held_round(
        &mut self,
        plan: &RoundPlan,
        held: &mut HeldBands,
        outcomes: Vec<HeldBandOutcome>,
    ) -> Result<TiledStep, BandError> {
        let mut digests = Vec::with_capacity(outcomes.len());
        for o in &outcomes {
            let rows = &o.outcome.rows;
            let expected = self.band_digest(held, rows);
            if o.from != expected {
                return Err(BandError::Foreign {
                    what: "the bands' outcomes",
                    problem: format!(
                        "the outcome of tile rows {rows:?} stepped held states of digest \
                         {:016x}, the band's are {expected:016x}: give this round's outcomes",
                        o.from
                    ),
                });
            }
            digests.push((rows.clone(), o.to));
        }
        let step = self.commit_round(plan, outcomes.into_iter().map(|o| o.outcome).collect())?;
        for (rows, d) in digests {
            held.digests.insert(rows.start, (rows, d));
        }
        Ok(step)
    }

    /// A copy of the state with the held bands' whole states spliced in: each of `held`'s
    /// bands must be given once, with its recorded digest (else refused, naming the band).
    pub fn with_held(&self, held: &HeldBands, bands: &[HeldBand]) -> Result<Self, BandError> {
        let mut whole = self.clone();
        let nx = self.geometry().grid().0;
        for (rows, d) in held.iter() {
            let band = bands.iter().find(|b| b.rows == *rows && b.digest() == d);
            let fits = |b: &&HeldBand| {
                b.tiles.len() == rows.len() * nx
                    && b.tiles
                        .iter()
                        .zip(rows.start * nx..)
                        .all(|(t, i)| t.index == i)
            };
            let Some(band) = band.filter(fits) else {
                return Err(BandError::Foreign {
                    what: "the held bands",
                    problem: format!(
                        "tile rows {rows:?}' states (digest {d:016x}) are held and not given: \
                         give every held band's states of this round"
                    ),
                });
            };
            whole.tiles[rows.start * nx..rows.end * nx].clone_from_slice(&band.tiles);
        }
        Ok(whole)
    }
}
