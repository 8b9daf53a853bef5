//! Rotation extraction: the proper rotation nearest to a deformation gradient, also for inverted
//! (det F < 0) and flat (rank-deficient) elements.
//!
//! The fast path maximises tr(Rᵀ F) over SO(3) by the fixed-point iteration of Müller, Bender,
//! Chentanez and Macklin ("A robust method to extract the rotational part of deformations",
//! MIG 2016), warm-started from the previous step's rotation. Every iterate is a unit quaternion,
//! so the result is a proper rotation whatever F is. The reference path (`polar_rotation_svd`)
//! is the SVD polar decomposition with the reflection moved to the smallest singular value; tests
//! check that both agree.

use crate::{Real, RotationStats};
use nalgebra::{Matrix3, Rotation3, Unit, UnitQuaternion};
use rayon::prelude::*;

/// Every frame's rotation from its deformation gradient `gradient(frame)`, warm-started from the
/// rotation in `rotations` and written over it, in parallel over the frames; counts the frames
/// whose gradient is inverted (det F ≤ 0). What `Discretization::write_rotations` does for every
/// backend; only how a frame's gradient is measured differs.
pub fn write_frame_rotations(
    rotations: &mut [Matrix3<Real>],
    max_iterations: usize,
    gradient: impl Fn(usize) -> Matrix3<Real> + Sync,
) -> RotationStats {
    let inverted = rotations
        .par_iter_mut()
        .enumerate()
        .map(|(frame, r)| {
            let f = gradient(frame);
            *r = extract_rotation(&f, r, max_iterations);
            usize::from(f.determinant() <= 0.0)
        })
        .sum();
    RotationStats { inverted }
}

/// Rotation that maximises tr(Rᵀ F), starting from `warm_start` (the previous rotation, or the
/// identity). Always a proper rotation (det R = +1), never NaN for finite F.
pub fn extract_rotation(f: &Matrix3<Real>, warm_start: &Matrix3<Real>, max_iterations: usize) -> Matrix3<Real> {
    let mut q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*warm_start));
    // Scale-free stopping: F may be anything from 1e-9 to 1e9 in magnitude.
    let scale = f.norm().max(Real::MIN_POSITIVE);
    for _ in 0..max_iterations {
        let r = q.to_rotation_matrix().into_inner();
        let torque =
            r.column(0).cross(&f.column(0)) + r.column(1).cross(&f.column(1)) + r.column(2).cross(&f.column(2));
        let alignment = r.column(0).dot(&f.column(0)) + r.column(1).dot(&f.column(1)) + r.column(2).dot(&f.column(2));
        let omega = torque / (alignment.abs() + 1e-9 * scale);
        let angle = omega.norm();
        // NaN angles stop too (partial_cmp is None).
        if angle.partial_cmp(&1e-12) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        q = UnitQuaternion::from_axis_angle(&Unit::new_unchecked(omega / angle), angle) * q;
        q.renormalize();
    }
    q.to_rotation_matrix().into_inner()
}

/// Reference polar rotation by SVD: `R = U diag(1, 1, det(U Vᵀ)) Vᵀ` with singular values sorted
/// so the possible reflection lands on the smallest one. Slow; used to check `extract_rotation`.
pub fn polar_rotation_svd(f: &Matrix3<Real>) -> Matrix3<Real> {
    let svd = f.svd(true, true);
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let smallest = svd.singular_values.imin();
    if (u * v_t).determinant() < 0.0 {
        u.column_mut(smallest).neg_mut();
    }
    u * v_t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pseudo_random(seed: &mut u64) -> Real {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
    }

    #[test]
    fn matches_svd_polar_on_random_gradients_including_inverted() {
        let mut seed = 7;
        let mut inverted = 0;
        for _ in 0..500 {
            let f = Matrix3::from_fn(|_, _| pseudo_random(&mut seed)) * 3.0;
            let r_svd = polar_rotation_svd(&f);
            let r = extract_rotation(&f, &Matrix3::identity(), 200);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-12);
            if f.determinant() < 0.0 {
                inverted += 1;
            }
            // Both maximise tr(RᵀF) over SO(3); compare the objective (the argmax can be
            // non-unique when the two smallest singular values coincide).
            let objective = |r: &Matrix3<Real>| (r.transpose() * f).trace();
            assert!(
                (objective(&r) - objective(&r_svd)).abs() < 1e-8 * f.norm(),
                "F = {f}: iterative {} vs svd {}",
                objective(&r),
                objective(&r_svd)
            );
            if f.determinant() > 0.1 {
                assert!((r - r_svd).norm() < 1e-6, "F = {f}");
            }
        }
        assert!(inverted > 100, "the sample must contain inverted gradients");
    }

    #[test]
    fn recovers_the_rotation_of_a_rotated_stretch() {
        let rotation = Rotation3::from_axis_angle(&nalgebra::Vector3::y_axis(), 2.5).into_inner();
        let stretch = Matrix3::new(2.0, 0.1, 0.0, 0.1, 0.5, 0.0, 0.0, 0.0, 1.0);
        let r = extract_rotation(&(rotation * stretch), &Matrix3::identity(), 100);
        assert!((r - rotation).norm() < 1e-9);
    }

    #[test]
    fn flat_and_zero_gradients_give_proper_rotations() {
        for f in [Matrix3::zeros(), Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0)] {
            let r = extract_rotation(&f, &Matrix3::identity(), 50);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            let r = polar_rotation_svd(&f);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
        }
    }
}
