//! Gauss–Legendre rules on [−1, 1] and their tensor products on boxes.

use crate::Real;

/// Points and weights of the `n`-point Gauss–Legendre rule on [−1, 1], exact for polynomials of
/// degree `2n − 1`. Supported `n`: 1..=6 (values from Abramowitz & Stegun, table 25.4).
pub fn gauss_legendre(n: usize) -> Option<(&'static [Real], &'static [Real])> {
    const P1: [Real; 1] = [0.0];
    const W1: [Real; 1] = [2.0];
    const P2: [Real; 2] = [-0.577_350_269_189_625_8, 0.577_350_269_189_625_8];
    const W2: [Real; 2] = [1.0, 1.0];
    const P3: [Real; 3] = [-0.774_596_669_241_483_4, 0.0, 0.774_596_669_241_483_4];
    const W3: [Real; 3] = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    const P4: [Real; 4] =
        [-0.861_136_311_594_052_6, -0.339_981_043_584_856_3, 0.339_981_043_584_856_3, 0.861_136_311_594_052_6];
    const W4: [Real; 4] =
        [0.347_854_845_137_453_9, 0.652_145_154_862_546_1, 0.652_145_154_862_546_1, 0.347_854_845_137_453_9];
    const P5: [Real; 5] =
        [-0.906_179_845_938_664, -0.538_469_310_105_683_1, 0.0, 0.538_469_310_105_683_1, 0.906_179_845_938_664];
    const W5: [Real; 5] = [
        0.236_926_885_056_189_1,
        0.478_628_670_499_366_5,
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
    ];
    const P6: [Real; 6] = [
        -0.932_469_514_203_152,
        -0.661_209_386_466_264_5,
        -0.238_619_186_083_196_9,
        0.238_619_186_083_196_9,
        0.661_209_386_466_264_5,
        0.932_469_514_203_152,
    ];
    const W6: [Real; 6] = [
        0.171_324_492_379_170_3,
        0.360_761_573_048_138_6,
        0.467_913_934_572_691,
        0.467_913_934_572_691,
        0.360_761_573_048_138_6,
        0.171_324_492_379_170_3,
    ];
    Some(match n {
        1 => (&P1, &W1),
        2 => (&P2, &W2),
        3 => (&P3, &W3),
        4 => (&P4, &W4),
        5 => (&P5, &W5),
        6 => (&P6, &W6),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_integrate_monomials_up_to_their_degree() {
        for n in 1..=6 {
            let (p, w) = gauss_legendre(n).unwrap();
            for degree in 0..2 * n {
                let exact = if degree % 2 == 1 { 0.0 } else { 2.0 / (degree as Real + 1.0) };
                let rule: Real = p.iter().zip(w).map(|(x, w)| w * x.powi(degree as i32)).sum();
                assert!((rule - exact).abs() < 1e-14, "n={n} degree={degree}: {rule} vs {exact}");
            }
            // and not one degree more (for even 2n): the rule is not exact there
            let degree = 2 * n;
            let exact = 2.0 / (degree as Real + 1.0);
            let rule: Real = p.iter().zip(w).map(|(x, w)| w * x.powi(degree as i32)).sum();
            assert!((rule - exact).abs() > 1e-6);
        }
        assert!(gauss_legendre(7).is_none());
    }
}
