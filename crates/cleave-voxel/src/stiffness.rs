//! The closed-form 24×24 stiffness of a trilinear cube element (mueller2004 appendix A,
//! re-derived in `docs/math/voxel-stiffness.md` because the paper's OCR is garbled).
//!
//! Corner `c = bx + 2·by + 4·bz` sits at `center + (h/2)·s_c` with `s_c = (2bx−1, 2by−1, 2bz−1)`.
//! DOF `3c + a` is component `a` of corner `c`.

use cleave_core::{Material, Real};

/// Sign vector `s_c ∈ {−1, +1}³` of cube corner `c`.
#[inline]
pub fn corner_signs(c: usize) -> [Real; 3] {
    [if c & 1 != 0 { 1.0 } else { -1.0 }, if c & 2 != 0 { 1.0 } else { -1.0 }, if c & 4 != 0 { 1.0 } else { -1.0 }]
}

/// Integer offset of corner `c` from the cube's minimum corner.
#[inline]
pub fn corner_offset(c: usize) -> [i32; 3] {
    [(c & 1) as i32, ((c >> 1) & 1) as i32, ((c >> 2) & 1) as i32]
}

/// `∫_cube ∂_a φ_i ∂_b φ_j dV` in closed form (docs/math/voxel-stiffness.md, eq. (3)–(4)).
pub fn gradient_product_integral(h: Real, i: usize, j: usize, a: usize, b: usize) -> Real {
    let (si, sj) = (corner_signs(i), corner_signs(j));
    if a == b {
        let mut product = 1.0;
        for k in (0..3).filter(|&k| k != a) {
            product *= 3.0 + si[k] * sj[k];
        }
        h / 144.0 * si[a] * sj[a] * product
    } else {
        let c = 3 - a - b;
        h / 48.0 * si[a] * sj[b] * (3.0 + si[c] * sj[c])
    }
}

/// The 24×24 stiffness of a cube of edge `h`, row-major: `K[(3i+a)·24 + 3j+b] =
/// λ I_ab + μ I_ba + μ δ_ab Σ_k I_kk` with `I_ab = ∫ ∂_a φ_i ∂_b φ_j`.
pub fn cube_stiffness(material: &Material, h: Real) -> [Real; 576] {
    let (lambda, mu) = material.lame();
    let mut k = [0.0; 576];
    for i in 0..8 {
        for j in 0..8 {
            let trace: Real = (0..3).map(|m| gradient_product_integral(h, i, j, m, m)).sum();
            for a in 0..3 {
                for b in 0..3 {
                    let mut value = lambda * gradient_product_integral(h, i, j, a, b)
                        + mu * gradient_product_integral(h, i, j, b, a);
                    if a == b {
                        value += mu * trace;
                    }
                    k[(3 * i + a) * 24 + 3 * j + b] = value;
                }
            }
        }
    }
    k
}
