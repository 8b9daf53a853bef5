//! Isotropic linear elastic material with Rayleigh damping, validated on construction.

use crate::Real;
use serde::{Deserialize, Serialize};

/// An isotropic Hookean material: Young's modulus `E` [Pa], Poisson ratio `ν` [-], density `ρ`
/// [kg/m³] and Rayleigh damping `D = αM + βK` (`α` [1/s], `β` [s]).
///
/// Construct with [`Material::new`]; the fields are public for reading, and [`Material::validate`]
/// re-checks a value that was built or deserialized by hand.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Young's modulus `E` in Pa; must be finite and > 0.
    pub youngs_modulus: Real,
    /// Poisson ratio `ν`; must lie in the open interval (−1, 0.5).
    pub poisson_ratio: Real,
    /// Mass density `ρ` in kg/m³; must be finite and > 0.
    pub density: Real,
    /// Mass-proportional Rayleigh damping `α` in 1/s; finite and ≥ 0.
    #[serde(default)]
    pub rayleigh_alpha: Real,
    /// Stiffness-proportional Rayleigh damping `β` in s; finite and ≥ 0.
    #[serde(default)]
    pub rayleigh_beta: Real,
    /// Tensile strength in Pa: the largest principal stress the material bears before it
    /// fractures (backends that fracture, `Fracturable`); `None` is unbreakable. Finite and > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tensile_strength: Option<Real>,
}

/// Why a material was rejected; every variant carries the offending value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MaterialError {
    /// `E ≤ 0` or not finite.
    #[error("Young's modulus must be finite and > 0 Pa, got {0}")]
    YoungsModulus(Real),
    /// `ν ∉ (−1, 0.5)`.
    #[error(
        "Poisson ratio must lie in (-1, 0.5) (0.5 is perfectly incompressible and has no finite \
         Lamé λ), got {0}"
    )]
    PoissonRatio(Real),
    /// `ρ ≤ 0` or not finite.
    #[error("density must be finite and > 0 kg/m^3, got {0}")]
    Density(Real),
    /// A tensile strength that is not finite and positive.
    #[error("tensile strength must be finite and > 0 Pa, got {0}")]
    TensileStrength(Real),
    /// A negative or non-finite damping coefficient.
    #[error("Rayleigh damping coefficients must be finite and >= 0, got alpha = {alpha}, beta = {beta}")]
    Damping {
        /// the mass-proportional coefficient given
        alpha: Real,
        /// the stiffness-proportional coefficient given
        beta: Real,
    },
}

impl Material {
    /// A validated undamped material.
    pub fn new(youngs_modulus: Real, poisson_ratio: Real, density: Real) -> Result<Self, MaterialError> {
        let material = Self {
            youngs_modulus,
            poisson_ratio,
            density,
            rayleigh_alpha: 0.0,
            rayleigh_beta: 0.0,
            tensile_strength: None,
        };
        material.validate()?;
        Ok(material)
    }

    /// The same material with Rayleigh damping `D = αM + βK`.
    pub fn with_damping(mut self, alpha: Real, beta: Real) -> Result<Self, MaterialError> {
        self.rayleigh_alpha = alpha;
        self.rayleigh_beta = beta;
        self.validate()?;
        Ok(self)
    }

    /// The same material breaking at the tensile strength `strength` [Pa].
    pub fn with_tensile_strength(mut self, strength: Real) -> Result<Self, MaterialError> {
        self.tensile_strength = Some(strength);
        self.validate()?;
        Ok(self)
    }

    /// Checks every field; the first offending one is reported.
    pub fn validate(&self) -> Result<(), MaterialError> {
        let e = self.youngs_modulus;
        if !(e.is_finite() && e > 0.0) {
            return Err(MaterialError::YoungsModulus(e));
        }
        let nu = self.poisson_ratio;
        if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
            return Err(MaterialError::PoissonRatio(nu));
        }
        let rho = self.density;
        if !(rho.is_finite() && rho > 0.0) {
            return Err(MaterialError::Density(rho));
        }
        let (alpha, beta) = (self.rayleigh_alpha, self.rayleigh_beta);
        if !(alpha.is_finite() && alpha >= 0.0 && beta.is_finite() && beta >= 0.0) {
            return Err(MaterialError::Damping { alpha, beta });
        }
        if let Some(strength) = self.tensile_strength
            && !(strength.is_finite() && strength > 0.0)
        {
            return Err(MaterialError::TensileStrength(strength));
        }
        Ok(())
    }

    /// Lamé parameters `(λ, μ)`: `λ = Eν/((1+ν)(1−2ν))`, `μ = E/(2(1+ν))`.
    pub fn lame(&self) -> (Real, Real) {
        let (e, nu) = (self.youngs_modulus, self.poisson_ratio);
        (e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu)))
    }

    /// The dilatational wave speed `sqrt((λ+2μ)/ρ)` in m/s, the fastest signal in the solid.
    pub fn p_wave_speed(&self) -> Real {
        let (lambda, mu) = self.lame();
        ((lambda + 2.0 * mu) / self.density).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_each_bad_field_with_its_value() {
        assert_eq!(Material::new(0.0, 0.3, 1.0), Err(MaterialError::YoungsModulus(0.0)));
        assert_eq!(Material::new(-5.0, 0.3, 1.0), Err(MaterialError::YoungsModulus(-5.0)));
        assert_eq!(Material::new(1.0, 0.5, 1.0), Err(MaterialError::PoissonRatio(0.5)));
        assert_eq!(Material::new(1.0, -1.0, 1.0), Err(MaterialError::PoissonRatio(-1.0)));
        assert_eq!(Material::new(1.0, 0.3, 0.0), Err(MaterialError::Density(0.0)));
        assert!(Material::new(1.0, Real::NAN, 1.0).is_err());
        let m = Material::new(1.0, 0.3, 1.0).unwrap();
        assert!(matches!(m.with_damping(-1.0, 0.0), Err(MaterialError::Damping { .. })));
        assert_eq!(m.with_tensile_strength(-2.0), Err(MaterialError::TensileStrength(-2.0)));
        assert!(m.with_tensile_strength(Real::INFINITY).is_err());
        assert_eq!(m.with_tensile_strength(3e4).unwrap().tensile_strength, Some(3e4));
        let message = Material::new(1.0, 0.5, 1.0).unwrap_err().to_string();
        assert!(message.contains("0.5"), "{message}");
    }

    #[test]
    fn lame_parameters_recover_young_and_poisson() {
        // E = μ(3λ+2μ)/(λ+μ), ν = λ/(2(λ+μ)): the inverse relations, independent of `lame`.
        let m = Material::new(2.5e6, 0.37, 900.0).unwrap();
        let (l, mu) = m.lame();
        assert!((mu * (3.0 * l + 2.0 * mu) / (l + mu) - 2.5e6).abs() < 1e-6);
        assert!((l / (2.0 * (l + mu)) - 0.37).abs() < 1e-14);
    }
}
