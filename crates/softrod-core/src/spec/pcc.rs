//! The `[pcc]` table of a design: the piecewise-constant-curvature model's parameters
//! (paper 003), validated with the rest of the design. The model itself is `crate::pcc`.

use crate::error::{Result, SoftrodError};
use serde::{Deserialize, Serialize};

/// Bending stiffness k_theta as a function of the bending angle theta (paper 003 Fig. 5c).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PccTable {
    /// Bending angles, rad, strictly increasing from >= 0.
    pub angle: Vec<f64>,
    /// k_theta at those angles, N m/rad, > 0; linear in between, constant beyond the ends.
    pub stiffness: Vec<f64>,
}

/// Where the mass sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MassModel {
    /// Integrated along the arc, with the cross-sections' rotary inertia.
    #[default]
    Distributed,
    /// All of the rod's mass at the tip, no rotary inertia (paper 003 eq. 6).
    Tip,
}

/// How chamber pressures enter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PressureModel {
    /// Virtual work p A delta(chamber length): conservative, same as the rod's law.
    #[default]
    Chamber,
    /// Follower forces p A d3 at the chamber centroids of the segment's tip (paper 003
    /// eqs. 9-13, Table I).
    TipForce,
}

fn default_quadrature() -> usize {
    8
}

/// The `[pcc]` table of a design (SI). Values left out are derived from the rod's
/// stiffnesses: k_L = c_e EA / L0, k_theta = c_b EI_22 / L0, k_phi = c_b (EI_11 - EI_22) / L0,
/// b = tau k with tau = `dynamics.damping_time`. Given values apply to every section with
/// chambers; sections without chambers always use the derived ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PccSpec {
    /// Longitudinal stiffness k_L, N/m.
    #[serde(default)]
    pub k_l: Option<f64>,
    /// Longitudinal damping b_L, N s/m.
    #[serde(default)]
    pub b_l: Option<f64>,
    /// Bending stiffness k_theta, N m/rad (constant) ...
    #[serde(default)]
    pub k_theta: Option<f64>,
    /// ... or as a function of theta.
    #[serde(default)]
    pub k_theta_table: Option<PccTable>,
    /// Bending damping b_theta, N m s/rad.
    #[serde(default)]
    pub b_theta: Option<f64>,
    /// Extra stiffness for bending towards d2: elastic energy 1/2 k_phi theta_y^2, N m/rad.
    #[serde(default)]
    pub k_phi: Option<f64>,
    /// Extra damping for bending towards d2: dissipation 1/2 b_phi theta_y_t^2, N m s/rad.
    #[serde(default)]
    pub b_phi: Option<f64>,
    #[serde(default)]
    pub mass_model: MassModel,
    #[serde(default)]
    pub pressure_force: PressureModel,
    /// Planar model (paper eq. 12): bending only in the plane at this angle from d1, rad.
    #[serde(default)]
    pub plane: Option<f64>,
    /// Gauss-Legendre nodes per segment for the mass integrals.
    #[serde(default = "default_quadrature")]
    pub quadrature: usize,
}

impl Default for PccSpec {
    fn default() -> Self {
        PccSpec {
            k_l: None,
            b_l: None,
            k_theta: None,
            k_theta_table: None,
            b_theta: None,
            k_phi: None,
            b_phi: None,
            mass_model: MassModel::Distributed,
            pressure_force: PressureModel::Chamber,
            plane: None,
            quadrature: default_quadrature(),
        }
    }
}

pub(crate) fn check(field: &str, x: f64, ok: bool, rule: &str) -> Result<()> {
    if x.is_finite() && ok {
        Ok(())
    } else {
        Err(SoftrodError::invalid(field, x, rule))
    }
}

impl PccSpec {
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("k_L", self.k_l), ("k_theta", self.k_theta)] {
            if let Some(x) = v {
                check(
                    &format!("pcc.{name}"),
                    x,
                    x > 0.0,
                    "must be a finite number > 0",
                )?;
            }
        }
        for (name, v) in [
            ("b_L", self.b_l),
            ("b_theta", self.b_theta),
            ("b_phi", self.b_phi),
        ] {
            if let Some(x) = v {
                check(
                    &format!("pcc.{name}"),
                    x,
                    x >= 0.0,
                    "must be a finite number >= 0",
                )?;
            }
        }
        if let Some(x) = self.k_phi {
            check("pcc.k_phi", x, true, "must be a finite number")?;
        }
        if self.k_theta.is_some() && self.k_theta_table.is_some() {
            return Err(SoftrodError::invalid(
                "pcc.k_theta",
                "a number and a table",
                "give k_theta either as a constant or as a table of angle and stiffness, not both",
            ));
        }
        if let Some(t) = &self.k_theta_table {
            let n = t.angle.len().max(t.stiffness.len());
            if n > crate::validity::MAX_TABLE_POINTS {
                return Err(SoftrodError::invalid(
                    "pcc.k_theta.angle",
                    format!("{n} points"),
                    format!(
                        "the k_theta table may have at most {} points",
                        crate::validity::MAX_TABLE_POINTS
                    ),
                ));
            }
            if t.angle.len() != t.stiffness.len() || t.angle.len() < 2 {
                return Err(SoftrodError::invalid(
                    "pcc.k_theta.angle",
                    format!(
                        "{} angles, {} stiffnesses",
                        t.angle.len(),
                        t.stiffness.len()
                    ),
                    "the k_theta table needs at least 2 angles and one stiffness per angle",
                ));
            }
            for (i, (&a, &k)) in t.angle.iter().zip(&t.stiffness).enumerate() {
                let ok = a >= 0.0 && (i == 0 || a > t.angle[i - 1]);
                check(
                    &format!("pcc.k_theta.angle[{i}]"),
                    a,
                    ok,
                    "angles must be >= 0 and strictly increasing",
                )?;
                check(
                    &format!("pcc.k_theta.stiffness[{i}]"),
                    k,
                    k > 0.0,
                    "must be a finite number > 0",
                )?;
            }
        }
        if let Some(p) = self.plane {
            check("pcc.plane", p, true, "must be a finite angle")?;
        }
        if !(2..=32).contains(&self.quadrature) {
            return Err(SoftrodError::invalid(
                "pcc.quadrature",
                self.quadrature,
                "must be between 2 and 32 Gauss-Legendre nodes per segment",
            ));
        }
        Ok(())
    }
}
