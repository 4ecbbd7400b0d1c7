//! The plan's calls on its state: start, advance, reconstruct (module docs of
//! [`super`]), and the state as JSON.

use std::path::{Path, PathBuf};

use super::{
    fingerprint, parse_hex, IssuedRound, PlanReconstruction, PlanState, PlanStep, ProtocolError,
    STATE_FORMAT, STATE_VERSION,
};
use crate::image::adaptive::correction::output_pixels;
use crate::image::adaptive::{
    fallback_note, fitting_solver, mix64, AdaptiveError, AdaptiveParams, Decision, FitState,
    ImagePlan, PixelEstimate, PlanProgress, SamplePositions, TreeGram, TreeSolver,
};
use crate::image::{DroppedSamples, ImagePlane, ImageSamples};

use super::{
    samples_fingerprint, CarriedFinal, CarriedGram, CarriedPcg, CarriedRows, FinalFit, ResumedPlan,
};

/// The state file's name, as the state's own faults name it.
const STATE_FILE: &str = "state.json";

impl PlanState {
    /// Refuses to start a new plan in the folder `dir` when it holds one already: its state
    /// file ([`PlanState::path`]) or any of `other_states` (the state files of other kinds of
    /// plan, e.g. a tiled one) exists, unless `overwrite`. The one check of every front end
    /// that starts a plan in a folder.
    pub fn check_new(
        dir: &Path,
        other_states: &[PathBuf],
        overwrite: bool,
    ) -> Result<(), ProtocolError> {
        let held = Self::path(dir).exists() || other_states.iter().any(|f| f.exists());
        if held && !overwrite {
            return Err(ProtocolError::HoldsPlan {
                dir: dir.to_path_buf(),
            });
        }
        Ok(())
    }

    /// The state as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a plan state serialises")
    }

    /// Parses a state written by [`PlanState::to_json`] (`file` names it in errors), checking
    /// its format, version and history against its own parameters.
    pub fn from_json(text: &str, file: &Path) -> Result<Self, ProtocolError> {
        let mut state: Self = serde_json::from_str(text).map_err(|e| ProtocolError::State {
            file: file.to_path_buf(),
            problem: e.to_string(),
        })?;
        state.check_layout(file)?;
        let plan =
            ImagePlan::resume(state.plane, &state.params, state.progress.clone()).map_err(|e| {
                match e {
                    // A memory limit below the plan's budget is no fault of the state.
                    AdaptiveError::Resource(e) => ProtocolError::Adaptive(e.into()),
                    e => ProtocolError::State {
                        file: file.to_path_buf(),
                        problem: e.to_string(),
                    },
                }
            })?;
        // kept for the calls on this state (resumed once, not again per use)
        state.resumed = ResumedPlan(Some(plan));
        Ok(state)
    }

    /// The tag of this plan's carried normal matrix: a hash of the state's version, plane
    /// and parameters (a matrix of another plan is not continued).
    pub fn tag(&self) -> u64 {
        let params = serde_json::to_string(&self.params).expect("parameters serialise");
        format!("{}/{}/{params}", STATE_VERSION, self.plane)
            .bytes()
            .fold(0u64, |h, b| mix64(h ^ u64::from(b)))
    }

    /// Functions of the plan's basis at its depth limit (the length of a carried PCG
    /// start, [`CarriedPcg::from_bytes`]).
    pub fn basis_len(&self) -> Result<usize, ProtocolError> {
        if let Some(plan) = self.resumed.of(self.plane, &self.params, &self.progress) {
            return Ok(plan.tree().basis().len());
        }
        Ok(ImagePlan::new(self.plane, &self.params)?
            .tree()
            .basis()
            .len())
    }

    /// Starts a plan: the state and the base positions for the seed.
    pub fn start(
        plane: ImagePlane,
        params: &AdaptiveParams,
    ) -> Result<(Self, SamplePositions), ProtocolError> {
        let plan = ImagePlan::new(plane, params)?;
        let base = plan.base_positions();
        let mut state = Self {
            format: STATE_FORMAT.into(),
            version: STATE_VERSION,
            plane,
            params: *params,
            channels: None,
            progress: plan.progress().clone(),
            issued: vec![IssuedRound {
                round: 0,
                positions: base.len(),
                total: base.len(),
                fingerprint: format!("{:016x}", fingerprint(0, &base.xs, &base.ys)),
            }],
            stop: None,
            carried: CarriedGram::default(),
            pcg: CarriedPcg::default(),
            final_fit: CarriedFinal::default(),
            rows: CarriedRows::default(),
            resumed: ResumedPlan::default(),
        };
        state.resumed = ResumedPlan(Some(plan));
        Ok((state, base))
    }

    /// Refuses `plane` and `params` unless they are the state's (each parameter compared by
    /// its serialised value; the first that differs is named).
    pub fn check_params(
        &self,
        plane: ImagePlane,
        params: &AdaptiveParams,
    ) -> Result<(), ProtocolError> {
        if plane != self.plane {
            return Err(ProtocolError::OtherParameters {
                parameter: "resolution".into(),
                state: self.plane.to_string(),
                given: plane.to_string(),
            });
        }
        let ours = serde_json::to_value(self.params).expect("parameters serialise");
        let theirs = serde_json::to_value(params).expect("parameters serialise");
        if let (Some(a), Some(b)) = (ours.as_object(), theirs.as_object()) {
            for (key, value) in a {
                let other = b.get(key).cloned().unwrap_or_default();
                if *value != other {
                    return Err(ProtocolError::OtherParameters {
                        parameter: key.clone(),
                        state: value.to_string(),
                        given: other.to_string(),
                    });
                }
            }
        }
        Ok(())
    }

    /// The last round handed out.
    pub fn round(&self) -> usize {
        self.issued.last().map_or(0, |r| r.round)
    }

    /// Positions handed out so far.
    pub fn positions(&self) -> usize {
        self.issued.last().map_or(0, |r| r.total)
    }

    /// The index into [`PlanState::issued`] whose positions are exactly those of `samples`
    /// and `dropped` together.
    fn matching_round(
        &self,
        samples: &ImageSamples,
        dropped: &DroppedSamples,
    ) -> Result<usize, ProtocolError> {
        if samples.plane() != self.plane {
            return Err(ProtocolError::Plane {
                state: self.plane,
                given: samples.plane(),
            });
        }
        if let Some(c) = self.channels {
            if c != samples.channels() {
                return Err(ProtocolError::Channels {
                    state: c,
                    given: samples.channels(),
                });
            }
        }
        let f = fingerprint(
            fingerprint(0, samples.xs(), samples.ys()),
            &dropped.xs,
            &dropped.ys,
        );
        let given = samples.len() + dropped.xs.len();
        let found = self
            .issued
            .iter()
            .position(|r| r.total == given && parse_hex(&r.fingerprint) == Some(f));
        let last = self.issued.len() - 1;
        match found {
            Some(k) => Ok(k),
            None => Err(ProtocolError::Mismatch {
                given,
                expected: self.positions(),
                round: last,
            }),
        }
    }

    /// The plan as of round `k` (the tree after the markings of rounds `1..=k`), fitting by
    /// `solver`.
    fn plan_at(&self, k: usize, solver: TreeSolver) -> Result<ImagePlan, ProtocolError> {
        let mut params = self.params;
        params.fit.solver = solver;
        if k == self.progress.marked.len() {
            if let Some(plan) = self.resumed.of(self.plane, &params, &self.progress) {
                return Ok(plan.clone());
            }
        }
        let progress = if k == self.progress.marked.len() {
            self.progress.clone()
        } else {
            PlanProgress {
                marked: self.progress.marked[..k].to_vec(),
                samples_fitted: 0,
            }
        };
        ImagePlan::resume(self.plane, &params, progress).map_err(|e| match e {
            AdaptiveError::History { .. } => ProtocolError::State {
                file: PathBuf::from(STATE_FILE),
                problem: e.to_string(),
            },
            e => e.into(),
        })
    }

    /// The plan as of round `k` fitting by the plan's solver, or by PCG when the direct fit
    /// of `samples` would not fit in memory (with the note saying so); refused, before the
    /// fit, when the fit, the output image and the `next` positions it may hand out exceed
    /// the memory limit under PCG too ([`fitting_solver`]): the tree has at most the base
    /// levels plus one per round, up to the depth limit.
    fn fitting_plan(
        &self,
        k: usize,
        samples: &ImageSamples,
        next: usize,
    ) -> Result<(ImagePlan, Option<String>), ProtocolError> {
        use crate::resources::tree_levels;
        let plan = self.plan_at(k, self.params.fit.solver)?;
        let p = self.params.tree.p;
        let limit = tree_levels(p, self.plane.width(), self.plane.height(), {
            self.params.quad.below_pixel
        });
        let levels = (plan.base_steps() + plan.progress().marked.len() as u32 + 1).min(limit);
        let sizes = (samples.len(), samples.channels(), next);
        let (solver, note) = fitting_solver(
            self.params.fit.solver,
            self.plane,
            (p, levels, self.params.tree.rho),
            sizes,
        )
        .map_err(|e| ProtocolError::Adaptive(e.into()))?;
        if solver == self.params.fit.solver {
            return Ok((plan, None));
        }
        Ok((self.plan_at(k, solver)?, note))
    }

    /// PCG's carried start and diagonal put into `plan` ([`CarriedPcg::offer`]); the note
    /// of what was set aside.
    fn offer_pcg(&self, plan: &mut ImagePlan, samples: &ImageSamples) -> Option<String> {
        let (start, diagonal, note) = self.pcg.offer(samples.xs(), samples.ys());
        plan.fit_state_mut().diagonal = diagonal;
        *plan.start_mut() = start;
        note
    }

    /// Checks the state's own consistency: format, version, one issued record per round.
    fn check_layout(&self, file: &Path) -> Result<(), ProtocolError> {
        let bad = |problem: String| ProtocolError::State {
            file: file.to_path_buf(),
            problem,
        };
        if self.format != STATE_FORMAT {
            return Err(bad(format!(
                "format `{}`, expected `{STATE_FORMAT}`",
                self.format
            )));
        }
        if self.version != STATE_VERSION {
            return Err(bad(format!(
                "version {}, this build reads version {STATE_VERSION}",
                self.version
            )));
        }
        if self.issued.len() != self.progress.marked.len() + 1
            || self.issued.iter().enumerate().any(|(i, r)| r.round != i)
            || self
                .issued
                .iter()
                .any(|r| parse_hex(&r.fingerprint).is_none())
        {
            return Err(bad(format!(
                "{} records of handed-out positions for {} rounds",
                self.issued.len(),
                self.progress.marked.len() + 1
            )));
        }
        Ok(())
    }

    /// One round on every sample so far: the fit on the tree, then the next positions (recorded
    /// as handed out) or the stop. The samples must be the positions handed out so far.
    pub fn advance(&mut self, samples: &ImageSamples) -> Result<PlanStep, ProtocolError> {
        self.advance_dropped(samples, DroppedSamples::default())
    }

    /// [`PlanState::advance`] on the finite `samples` of a round whose non-finite samples
    /// were `dropped` (their positions complete the round; module docs). On an error the
    /// state is unchanged.
    pub fn advance_dropped(
        &mut self,
        samples: &ImageSamples,
        dropped: DroppedSamples,
    ) -> Result<PlanStep, ProtocolError> {
        self.advance_imaging(samples, dropped, true)
    }

    /// [`PlanState::advance_dropped`], making the stopping round's output pixels
    /// ([`PlanStep::reconstruction`]) only with `image_at_stop`: a caller that makes the final
    /// image another way (the plan's final-image job under an iterative solver, which solves
    /// again from the carried coefficients) skips their cost. The round is the same either
    /// way.
    pub fn advance_imaging(
        &mut self,
        samples: &ImageSamples,
        dropped: DroppedSamples,
        image_at_stop: bool,
    ) -> Result<PlanStep, ProtocolError> {
        let started = std::time::Instant::now();
        let k = self.matching_round(samples, &dropped)?;
        let last = self.issued.len() - 1;
        if k < last {
            return Err(ProtocolError::AlreadyPlanned {
                given: samples.len() + dropped.xs.len(),
                matched: k,
                round: last,
                expected: self.positions(),
            });
        }
        let next = self.params.stop.budget.saturating_sub(self.positions());
        let (mut plan, mut solver_note) = self.fitting_plan(k, samples, next)?;
        let values: Vec<&[f64]> = samples.values().iter().map(|v| v.as_slice()).collect();
        let carried = self.carried.gram.take();
        let mut gram_note = self.carried.note.take();
        let offered = carried.as_ref().map(TreeGram::samples);
        plan.fit_state_mut().gram = carried;
        let mut pcg_note = self.offer_pcg(&mut plan, samples);
        // the rows of the samples fitted before, read back instead of evaluated again
        let tag = self.tag();
        if self.rows.bytes.is_none() && self.rows.is_empty() && !self.progress.marked.is_empty() {
            self.rows.note = Some(format!(
                "{}: not found, although the plan has fitted {} round(s) (removed, or \
                 the last call could not write it); the single-scale rows of every sample \
                 evaluated afresh (the same rows, more time)",
                super::carried_rows::ROWS_FILE,
                self.progress.marked.len()
            ));
        }
        plan.fit_state_mut().rows =
            self.rows
                .offer(tag, plan.tree().basis(), samples.xs(), samples.ys());
        let mut stepped = plan.step(samples.xs(), samples.ys(), &values);
        if let Err(AdaptiveError::Resource(e)) = &stepped {
            // the fit's own, finer estimate refused the direct solve: PCG instead
            if !matches!(plan.params().fit.solver, TreeSolver::Pcg { .. }) {
                solver_note = Some(fallback_note(e));
                let rows = plan.fit_state_mut().rows.take();
                plan = self.plan_at(k, TreeSolver::plan_pcg())?;
                pcg_note = self.offer_pcg(&mut plan, samples);
                plan.fit_state_mut().rows = rows;
                stepped = plan.step(samples.xs(), samples.ys(), &values);
            }
        }
        if let Some(note) = self.rows.note.take() {
            pcg_note = Some(match pcg_note {
                Some(n) => format!("{n}; {note}"),
                None => note,
            });
        }
        self.carried.gram = plan.fit_state_mut().gram.take();
        self.pcg = CarriedPcg {
            start: plan.start_mut().take(),
            diagonal: plan.fit_state_mut().diagonal.take(),
            note: None,
        };
        let round = stepped?;
        // a stopped plan fits no more rounds: it keeps no rows
        let rows = plan.fit_state_mut().rows.take();
        let rows = rows.filter(|_| matches!(round.decision, Decision::Sample(_)));
        self.rows.keep(tag, rows, samples.xs(), samples.ys());
        let direct = round.log.fit.solver == "direct";
        if let Some(m) = offered.filter(|_| direct && round.log.fit.normal_kept_samples == 0) {
            gram_note.get_or_insert(format!(
                "the carried normal matrix ({m} samples) was not continued: the samples do not \
                 start with its samples in the same order, or the tree lost functions; \
                 assembled afresh"
            ));
        }
        // A stopping round's fit is the final fit (the tree is unchanged by the stop): its
        // output pixels are those `reconstruct` would compute again from the same samples.
        // It is carried ([`FinalFit`]): every final image of these samples is made from it,
        // without a second solve.
        let final_fit = match round.decision {
            Decision::Stop(_) => Some(FinalFit {
                samples: samples.len(),
                channels: samples.channels(),
                fingerprint: samples_fingerprint(samples),
                sigma: round.log.noise.as_ref().map_or(0.0, |n| n.sigma),
                fit: round.fit,
                solver_note: solver_note.clone(),
            }),
            Decision::Sample(_) => None,
        };
        let imaging = std::time::Instant::now();
        let reconstruction = match &final_fit {
            Some(done) if image_at_stop => Some(Box::new(self.final_image(
                &plan,
                done,
                samples,
                (k, dropped.clone()),
                self.params.output.pixels,
            )?)),
            Some(_) | None => None,
        };
        let image_s = imaging.elapsed().as_secs_f64();
        self.final_fit = CarriedFinal {
            fit: final_fit,
            note: None,
        };
        self.channels = Some(samples.channels());
        let (next, next_round, stop) = match round.decision {
            Decision::Sample(next) => {
                let prev = self.issued[last].clone();
                let start = parse_hex(&prev.fingerprint).expect("checked when loaded");
                self.issued.push(IssuedRound {
                    round: last + 1,
                    positions: next.len(),
                    total: prev.total + next.len(),
                    fingerprint: format!("{:016x}", fingerprint(start, &next.xs, &next.ys)),
                });
                self.progress = plan.progress().clone();
                // the plan kept is of the progress before this round's
                self.resumed = ResumedPlan::default();
                (next, Some(last + 1), None)
            }
            Decision::Stop(stop) => {
                self.stop = Some(stop);
                (SamplePositions::default(), None, Some(stop))
            }
        };
        Ok(PlanStep {
            log: round.log,
            next_positions: next.len(),
            next,
            next_round,
            stop,
            total_positions: self.positions(),
            budget: self.params.stop.budget,
            dropped,
            gram_note,
            pcg_note,
            solver_note,
            samples_note: None,
            round_s: started.elapsed().as_secs_f64(),
            image_s,
            reconstruction,
        })
    }

    /// The fit of `samples` (the positions of rounds `0..=k` handed out by this plan, for some
    /// `k`) on the tree they were planned for: after the markings of rounds `1..=k`, and the
    /// output pixels the plan's parameters ask for (`AdaptiveParams::pixels`). With the
    /// samples of the round at which the plan stopped, this is the in-process loop's result.
    pub fn reconstruct(&self, samples: &ImageSamples) -> Result<PlanReconstruction, ProtocolError> {
        self.reconstruct_as(samples, self.params.output.pixels)
    }

    /// [`PlanState::reconstruct`] with the output pixels `estimate` instead of the plan's
    /// (the fit, its noise estimate and `z` are the plan's: the rounds do not depend on it).
    pub fn reconstruct_as(
        &self,
        samples: &ImageSamples,
        estimate: PixelEstimate,
    ) -> Result<PlanReconstruction, ProtocolError> {
        self.reconstruct_dropped(samples, DroppedSamples::default(), estimate)
    }

    /// [`PlanState::reconstruct_as`] on the finite `samples` of rounds whose non-finite
    /// samples were `dropped` (module docs).
    pub fn reconstruct_dropped(
        &self,
        samples: &ImageSamples,
        dropped: DroppedSamples,
        estimate: PixelEstimate,
    ) -> Result<PlanReconstruction, ProtocolError> {
        let k = self.matching_round(samples, &dropped)?;
        let stopped_at = self.stop.is_some() && k + 1 == self.issued.len();
        let fit_note = match &self.final_fit.fit {
            Some(done) if stopped_at && done.fits(samples) => {
                let plan = self.plan_at(k, self.params.fit.solver)?;
                return self.final_image(&plan, done, samples, (k, dropped), estimate);
            }
            Some(done) if stopped_at => Some(format!(
                "the stopping round's fit ({} samples) is not used: these samples are not the \
                 ones it fitted (other values or another count); fitted again",
                done.samples
            )),
            None if stopped_at => Some(self.final_fit.note.clone().unwrap_or_else(|| {
                "the stopping round's fit is not carried with this state; fitted again (the \
                 same tolerance, other bits than the plan's own final image)"
                    .into()
            })),
            Some(_) | None => None,
        };
        let (mut plan, solver_note) = self.fitting_plan(k, samples, 0)?;
        let values: Vec<&[f64]> = samples.values().iter().map(|v| v.as_slice()).collect();
        // the carried normal matrix, continued (the same bits as assembled afresh), and
        // PCG's carried start and diagonal
        self.offer_pcg(&mut plan, samples);
        let start = plan.start_mut().take();
        let mut carried = FitState {
            gram: self.carried.gram.clone(),
            diagonal: plan.fit_state_mut().diagonal.take(),
            ..FitState::default()
        };
        let (fit, significance) = plan.fit_updating(
            samples.xs(),
            samples.ys(),
            &values,
            plan.params().fit.solver,
            start.as_deref(),
            &mut carried,
        )?;
        // the noise estimate of this fit, as the in-process loop's last round
        let sigma = significance.map_or(0.0, |s| s.level.sigma);
        let (fit_image, image, correction) = output_pixels(
            plan.tree(),
            &fit,
            samples.xs(),
            samples.ys(),
            samples.values(),
            estimate,
            sigma,
            self.params.output.residual_z,
        )?;
        Ok(PlanReconstruction {
            tree: plan.tree().clone(),
            fit,
            fit_image,
            image,
            correction,
            round: k,
            complete: stopped_at,
            dropped,
            solver_note,
            fit_note,
        })
    }

    /// The final image of the carried stopping round's fit `done` on `plan`'s tree (the
    /// samples of round `k`, with `dropped`): the output pixels `estimate` from its
    /// coefficients and its noise estimate, no solve.
    fn final_image(
        &self,
        plan: &ImagePlan,
        done: &FinalFit,
        samples: &ImageSamples,
        (k, dropped): (usize, DroppedSamples),
        estimate: PixelEstimate,
    ) -> Result<PlanReconstruction, ProtocolError> {
        let (fit_image, image, correction) = output_pixels(
            plan.tree(),
            &done.fit,
            samples.xs(),
            samples.ys(),
            samples.values(),
            estimate,
            done.sigma,
            self.params.output.residual_z,
        )?;
        Ok(PlanReconstruction {
            tree: plan.tree().clone(),
            fit: done.fit.clone(),
            fit_image,
            image,
            correction,
            round: k,
            complete: true,
            dropped,
            solver_note: done.solver_note.clone(),
            fit_note: None,
        })
    }
}
