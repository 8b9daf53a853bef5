//! Preconditioned conjugate gradients on caller-supplied operator and preconditioner closures,
//! with buffers owned by the caller so a step allocates nothing.

use cleave_core::Real;
use rayon::prelude::*;

/// Reusable CG vectors.
#[derive(Debug, Default)]
pub(crate) struct CgWorkspace {
    r: Vec<Real>,
    z: Vec<Real>,
    p: Vec<Real>,
    ap: Vec<Real>,
}

/// How a CG solve ended.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CgOutcome {
    pub iterations: usize,
    pub relative_residual: Real,
    pub converged: bool,
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.par_iter().with_min_len(4096).zip(b).map(|(a, b)| a * b).sum()
}

impl CgWorkspace {
    fn resize(&mut self, n: usize) {
        for v in [&mut self.r, &mut self.z, &mut self.p, &mut self.ap] {
            v.resize(n, 0.0);
        }
    }

    /// Three of the vectors, of length `n`, as scratch space for work between solves (a solve
    /// overwrites them before it reads them): the step's force, trial positions and stiffness
    /// actions live here instead of in their own arrays, 72 B a node less at a million voxels.
    /// Their contents are unspecified.
    pub fn spare(&mut self, n: usize) -> [&mut [Real]; 3] {
        self.resize(n);
        [&mut self.r, &mut self.z, &mut self.p]
    }

    /// Solves `A x = b` from the initial guess in `x`, until `‖r‖ ≤ tol · max(‖b‖, scale)`.
    ///
    /// `scale` is a floor for the right-hand side's norm: a body at rest has `b → 0` while the
    /// terms that make up `b` stay large, and a tolerance relative to `‖b‖` alone would then ask
    /// for ever more digits of a velocity that is already zero to within the load's scale.
    pub fn solve(
        &mut self,
        mut apply: impl FnMut(&[Real], &mut [Real]),
        mut precondition: impl FnMut(&[Real], &mut [Real]),
        b: &[Real],
        scale: Real,
        x: &mut [Real],
        tolerance: Real,
        max_iterations: usize,
    ) -> CgOutcome {
        self.resize(b.len());
        let Self { r, z, p, ap } = self;
        let b_norm = dot(b, b).sqrt().max(scale);
        if b_norm == 0.0 {
            x.fill(0.0);
            return CgOutcome { iterations: 0, relative_residual: 0.0, converged: true };
        }
        apply(x, ap);
        r.par_iter_mut().zip(b).zip(&*ap).for_each(|((r, b), ap)| *r = b - ap);
        precondition(r, z);
        p.copy_from_slice(z);
        let mut rz = dot(r, z);
        let mut residual = dot(r, r).sqrt() / b_norm;
        let mut iterations = 0;
        while residual > tolerance && iterations < max_iterations {
            apply(p, ap);
            let pap = dot(p, ap);
            if pap.is_nan() || pap <= 0.0 {
                // Not positive definite along p (or NaN): stop and let the caller report it.
                break;
            }
            let alpha = rz / pap;
            x.par_iter_mut().zip(&*p).for_each(|(x, p)| *x += alpha * p);
            r.par_iter_mut().zip(&*ap).for_each(|(r, ap)| *r -= alpha * ap);
            residual = dot(r, r).sqrt() / b_norm;
            iterations += 1;
            if residual <= tolerance {
                break;
            }
            precondition(r, z);
            let rz_new = dot(r, z);
            let beta = rz_new / rz;
            rz = rz_new;
            p.par_iter_mut().zip(&*z).for_each(|(p, z)| *p = z + beta * *p);
        }
        CgOutcome { iterations, relative_residual: residual, converged: residual <= tolerance }
    }
}
