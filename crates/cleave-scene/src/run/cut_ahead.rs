//! Cutting ahead: a timeline `Cut` applied to a copy of the body on threads of its own while the
//! steps before it run, swapped in when due.

use super::*;
use cleave_core::{Discretization, EmbeddedSurface, Piece, Real, TopologyChange, TopologyError};
use cleave_integrator::{Constraints, ContactSet};
use std::sync::Arc;
use std::time::Instant;

/// A timeline `Cut` applied to a copy of the body on threads of its own while the steps before
/// it run (the cut is in rest space: it does not depend on the motion), swapped in when due.
pub(super) struct PreparedCut {
    /// Index of the event in the timeline.
    pub(super) event: usize,
    /// Epoch of the body the copy was taken from: the copy is used only if the body is still
    /// at it when the cut is due (nothing else cut it in between).
    pub(super) epoch: u64,
    pub(super) handle: std::thread::JoinHandle<Result<CutCopy, TopologyError>>,
}

/// A copy of the body after a cut, with what the runner asks of the backend after one.
pub(super) struct CutCopy {
    pub(super) discretization: Box<dyn Discretization>,
    pub(super) change: TopologyChange,
    pub(super) surface: Option<EmbeddedSurface>,
    pub(super) pieces: Vec<Piece>,
    /// The integrator's contact structures of the new surface (with surface contact).
    pub(super) contact: Option<ContactSet>,
    /// Wall time the preparation took to copy and cut the body and make its surface, pieces and
    /// contact structures [s].
    pub(super) seconds: Real,
}

impl Simulation {
    /// Whether timeline `Cut`s are applied ahead to a copy of the body, off the step's thread,
    /// while the steps before them run (default: on). The result is the same bit for bit; off,
    /// a change's cost is all paid in the step it is due (what `compare` measures per change).
    pub fn set_cut_ahead(&mut self, on: bool) {
        self.cut_ahead = on;
        if !on && let Some(prepared) = self.prepared.take() {
            // Joined, not left running: it may still hold the body an in-place cut will change.
            let _ = prepared.handle.join();
        }
    }

    /// Starts applying the next timeline `Cut` to a copy of the body on threads of its own, if
    /// nothing can change the body before it (no blade acts before its time) and it is not due
    /// at the next step already. A backend that cannot copy itself
    /// (`Discretization::copy_for_cutting` gives `None`) ends the preparation at once, and the
    /// cut is made when due.
    pub(super) fn prepare_next_cut(&mut self) {
        if self.prepared.is_some() || !self.cut_ahead {
            return;
        }
        let now = self.integrator.time();
        let h = self.integrator.settings().time_step;
        let next = self
            .timeline
            .iter()
            .enumerate()
            .filter_map(|(k, e)| match e {
                TimedCut::Once { time, surface: Some(surface) } => Some((k, *time, surface)),
                _ => None,
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((event, time, surface)) = next else { return };
        let blade_before = self.timeline.iter().any(|e| match e {
            TimedCut::Blade { start, end, .. } => *start <= time + 1e-9 && *end > now,
            TimedCut::Once { .. } => false,
        });
        if blade_before || time <= now + h + 1e-9 {
            return;
        }
        let surface = surface.clone();
        let epoch = self.discretization.epoch();
        // The copy itself is made on the preparation's thread (40 ms on bunny_slice after its
        // first cuts): the body is shared until then, and the steps only read it.
        let body = Arc::clone(&self.discretization);
        let surface_contact = self.contact.surface_contact.clone();
        // As many threads as the step's pool, so the copy is cut exactly as the body would be
        // (per-thread chunking of the scatter plans) and the result is the same bit for bit.
        let threads = rayon::current_num_threads();
        let retired = self.retired.take();
        let spawned = std::thread::Builder::new().name("cleave-cut-ahead".into()).spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .thread_name(|k| format!("cleave-cut-ahead-{k}"))
                // What the step leaves of the cores (its sequential factorization, for one):
                // at the step's priority they took half of them, and the steps in between
                // slowed by as much (a step after a cut reached 119 ms). Where the priority
                // cannot be lowered they run at the step's.
                .start_handler(|_| {
                    let _ = thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Min);
                })
                .build()
                .map_err(|e| TopologyError::Invalid(format!("no threads to cut ahead on: {e}")))?;
            pool.install(move || {
                drop(retired);
                let clock = Instant::now();
                let copy = body.copy_for_cutting();
                drop(body);
                let mut discretization =
                    copy.ok_or_else(|| TopologyError::Invalid("the backend cannot copy itself to cut ahead".into()))?;
                let cuttable = discretization
                    .as_cuttable()
                    .ok_or_else(|| TopologyError::Invalid("the backend's copy cannot cut".into()))?;
                let change = cuttable.cut(&surface)?;
                let surface = cuttable.surface();
                let pieces = cuttable.pieces();
                // The contact structures the integrator builds from the new surface alone.
                let contact = surface_contact.zip(surface.as_ref()).map(|(settings, surface)| {
                    let constraints = Constraints {
                        contact_points: Some(surface.embedding.clone()),
                        surface_contact: Some(surface_contact_on(&settings, surface)),
                        ..Default::default()
                    };
                    ContactSet::new(&constraints.colliders(), discretization.rest_dofs())
                });
                Ok(CutCopy { discretization, change, surface, pieces, contact, seconds: clock.elapsed().as_secs_f64() })
            })
        });
        // No thread: the cut is made when due.
        if let Ok(handle) = spawned {
            self.prepared = Some(PreparedCut { event, epoch, handle });
        }
    }

    /// The prepared copy of timeline event `event` if it is ready to use (waiting for it if
    /// needed); `None` (and the preparation dropped) if there is none, or it was taken from a
    /// body that has changed since, or it failed (the cut is then made in place, which reports
    /// the failure if it fails again).
    pub(super) fn take_prepared(&mut self, event: Option<usize>) -> Option<CutCopy> {
        let prepared = self.prepared.take_if(|p| Some(p.event) == event)?;
        if prepared.epoch != self.discretization.epoch() {
            return None;
        }
        prepared.handle.join().ok()?.ok()
    }
}
