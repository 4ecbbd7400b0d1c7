//! The single-scale rows `E` of the samples a plan has fitted, carried from one call to the
//! next ([`CarriedRows`]; the plan folder's `rows.bin`, `io::plan_files`): a round's samples
//! are the earlier ones followed by the new ones, so a call evaluates only its new samples'
//! rows and reads the others back (an evaluation of `E` costs about 1 µs a sample; a row read
//! back, its 7 words for `p = 2`, a few nanoseconds). The file is a sequence of pieces
//! ([`SingleScaleRows::piece_bytes`]: tagged with the plan, checksummed, each with a hash of
//! its rows' positions), one appended by each call, so a call writes only its new rows.
//!
//! A cache: the rows read back are the evaluated ones bit for bit (the same values stored by
//! their bits), and rows that are not there, damaged, of another plan or of other positions
//! are evaluated afresh, with a note (the round's `rows_note`). A stopped plan removes it.

use crate::basis::tensor::TensorBasis;
use crate::image::adaptive::pcg::{positions_hash, SingleScaleRows};

/// The file of the carried rows inside the plan's folder.
pub const ROWS_FILE: &str = "rows.bin";

/// The rows a plan carries between calls (module docs).
#[derive(Clone, Debug, Default)]
pub struct CarriedRows {
    /// The file's bytes as read by the call (`None`: no file, or already parsed).
    pub bytes: Option<Vec<u8>>,
    /// The rows of the last fit, kept in memory (a plan driven in one process).
    rows: Option<SingleScaleRows>,
    /// The hash of `rows`' positions (`pcg::positions_hash`).
    positions: u64,
    /// The rows the file holds, a prefix of `rows`, and the bytes they fill.
    in_file: (usize, u64),
    /// The bytes to write and where: after the file's first bytes (`Some`), or as the whole
    /// file (`None`); nothing to write when `None` itself.
    piece: Option<(Vec<u8>, Option<u64>)>,
    /// Why the carried rows were not used, or not all of them (`None`: used, or none).
    pub note: Option<String>,
}

impl PartialEq for CarriedRows {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl CarriedRows {
    /// The rows of a prefix of the samples `(xs, ys)` on `basis`, for a fit to continue
    /// ([`SingleScaleRows::continued`]): those kept in memory if they are of the samples'
    /// first positions, else those read from the file's pieces (a note says what was set
    /// aside).
    pub fn offer(
        &mut self,
        tag: u64,
        basis: &TensorBasis,
        xs: &[f64],
        ys: &[f64],
    ) -> Option<SingleScaleRows> {
        if let Some(rows) = self.rows.take() {
            let n = rows.len();
            if n <= xs.len() && positions_hash(&xs[..n], &ys[..n]) == self.positions {
                return Some(rows);
            }
            self.in_file = (0, 0);
        }
        let bytes = self.bytes.take()?;
        let (rows, used, why) = SingleScaleRows::from_pieces(&bytes, tag, basis, xs, ys);
        let n = rows.as_ref().map_or(0, SingleScaleRows::len);
        if let Some(why) = why {
            self.note = Some(format!(
                "the carried single-scale rows were not all used ({why}): {n} of {} rows read \
                 back, the rest evaluated afresh (the same rows, more time)",
                xs.len()
            ));
        }
        self.in_file = (n, used);
        rows
    }

    /// Keeps the rows `rows` of the samples `(xs, ys)` fitted by this call (a fit on fewer
    /// or other samples keeps nothing) and prepares the bytes to write: the rows after the
    /// file's as a piece appended to it, or all of them as a fresh file.
    pub fn keep(&mut self, tag: u64, rows: Option<SingleScaleRows>, xs: &[f64], ys: &[f64]) {
        self.piece = None;
        let Some(rows) = rows.filter(|r| r.len() == xs.len() && !r.is_empty()) else {
            self.rows = None;
            return;
        };
        let (from, at) = match self.in_file {
            (n, used) if n > 0 && n <= rows.len() => (n, Some(used)),
            _ => (0, None),
        };
        if from < rows.len() || at.is_none() {
            self.piece = rows.piece_bytes(tag, from, xs, ys).map(|b| (b, at));
        }
        self.positions = positions_hash(xs, ys);
        self.rows = Some(rows);
    }

    /// The bytes to write, and where: after the file's first bytes (`Some`) or as the whole
    /// file (`None`); `None` when there is nothing new.
    pub fn piece(&self) -> Option<(&[u8], Option<u64>)> {
        self.piece.as_ref().map(|(b, at)| (b.as_slice(), *at))
    }

    /// Whether no rows are kept (the plan stopped, or the fit was not on these samples):
    /// the file, if any, is stale.
    pub fn is_empty(&self) -> bool {
        self.rows.is_none()
    }
}
