//! The compiled rod: a validated design turned into per-section stiffness, compliance,
//! weight and chamber data (all SI), ready for the integrator.

use crate::error::{Result, SoftrodError};
use crate::section::CrossSection;
use crate::spec::{validate_pressures, DesignSpec};

/// A chamber as the constitutive law sees it: pressurised area and centroid (d1, d2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chamber {
    pub area: f64,
    pub centroid: [f64; 2],
    pub channel: usize,
}

/// One compiled section.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    pub name: String,
    pub length: f64,
    pub steps: usize,
    pub rigid: bool,
    /// Diagonal of K_se = diag(c_s GA, c_s GA, c_e EA), N.
    pub k_se: [f64; 3],
    /// K_bt = [[c_b EI_11, c_b EI_12, 0], [c_b EI_12, c_b EI_22, 0], [0, 0, c_t GJ]], N m^2.
    pub k_bt: [[f64; 3]; 3],
    /// Inverse of K_se (diagonal), 1/N.
    pub c_se: [f64; 3],
    /// Inverse of K_bt, 1/(N m^2).
    pub c_bt: [[f64; 3]; 3],
    /// Mass per unit reference length, kg/m.
    pub line_mass: f64,
    /// User line loads on this section (world frame): force N/m and moment N m/m.
    pub line_force: [f64; 3],
    pub line_moment: [f64; 3],
    pub chambers: Vec<Chamber>,
    /// Arc length at the start of the section, m.
    pub s_start: f64,
}

/// A validated, compiled design. Immutable: solves never change it.
#[derive(Debug, Clone, PartialEq)]
pub struct Rod {
    pub spec: DesignSpec,
    pub sections: Vec<Section>,
    pub n_channels: usize,
    pub length: f64,
    pub base_position: [f64; 3],
    /// Base rotation R0, row-major (columns are d1, d2, d3 in world coordinates).
    pub base_rotation: [[f64; 3]; 3],
    pub gravity: [f64; 3],
    /// Force scale for the shooting unknowns and residual: a bending stiffness over L^2, N.
    pub force_scale: f64,
}

fn inverse3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if !(det.is_finite() && det > 0.0) {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (a, b) = ((j + 1) % 3, (j + 2) % 3);
            let (c, d) = ((i + 1) % 3, (i + 2) % 3);
            inv[i][j] = (m[a][c] * m[b][d] - m[a][d] * m[b][c]) / det;
        }
    }
    Some(inv)
}

impl Rod {
    /// Validate and compile a design.
    pub fn new(spec: DesignSpec) -> Result<Self> {
        spec.validate()?;
        let mut sections = Vec::with_capacity(spec.sections.len());
        let mut s_start = 0.0;
        for (i, s) in spec.sections.iter().enumerate() {
            let cs = s.outer_radius.map(|ro| CrossSection::from_spec(s, ro));
            if let Some(cs) = &cs {
                if cs.area <= 0.0 || cs.i11 <= 0.0 || cs.i22 <= 0.0 {
                    return Err(SoftrodError::invalid(
                        format!("sections[{i}].chambers"),
                        format!("A_m = {:.4e} m^2", cs.area),
                        "bore and chambers leave no positive material area / second moment",
                    ));
                }
            }
            let mat = s.material;
            let geo = |f: &dyn Fn(&CrossSection, &crate::spec::MaterialSpec) -> f64| -> f64 {
                match (&cs, &mat) {
                    (Some(cs), Some(m)) => f(cs, m),
                    _ => f64::NAN, // unreachable for validated elastic sections
                }
            };
            let st = &s.stiffness;
            let ea = st
                .ea
                .unwrap_or_else(|| geo(&|c, m| m.youngs_modulus * c.area));
            let ga = st
                .ga
                .unwrap_or_else(|| geo(&|c, m| m.shear_modulus * c.area));
            let ei1 = st
                .ei1
                .unwrap_or_else(|| geo(&|c, m| m.youngs_modulus * c.i11));
            let ei2 = st
                .ei2
                .unwrap_or_else(|| geo(&|c, m| m.youngs_modulus * c.i22));
            // The coupling term comes from the geometry only (direct stiffnesses describe
            // principal axes); zero when the section has no geometry.
            let ei12 = match (&cs, &mat) {
                (Some(c), Some(m)) if st.ei1.is_none() && st.ei2.is_none() => {
                    m.youngs_modulus * c.i12
                }
                _ => 0.0,
            };
            let gj = st
                .gj
                .unwrap_or_else(|| geo(&|c, m| m.shear_modulus * c.polar()));
            let k_se = [s.c_s * ga, s.c_s * ga, s.c_e * ea];
            let k_bt = [
                [s.c_b * ei1, s.c_b * ei12, 0.0],
                [s.c_b * ei12, s.c_b * ei2, 0.0],
                [0.0, 0.0, s.c_t * gj],
            ];
            let (c_se, c_bt) = if s.rigid {
                ([0.0; 3], [[0.0; 3]; 3])
            } else {
                let c_bt = inverse3(&k_bt).ok_or_else(|| {
                    SoftrodError::invalid(
                        format!("sections[{i}]"),
                        format!("K_bt = {k_bt:?}"),
                        "bending/torsion stiffness matrix must be positive definite",
                    )
                })?;
                ([1.0 / k_se[0], 1.0 / k_se[1], 1.0 / k_se[2]], c_bt)
            };
            let line_mass = match s.mass {
                Some(m) => m / s.length,
                None => geo(&|c, m| m.density * c.area),
            };
            let mut line_force = [0.0; 3];
            let mut line_moment = [0.0; 3];
            for l in spec.loads.iter().filter(|l| l.section == i) {
                for k in 0..3 {
                    line_force[k] += l.force_per_length[k];
                    line_moment[k] += l.moment_per_length[k];
                }
            }
            let chambers = s
                .chambers
                .iter()
                .map(|c| Chamber {
                    area: c.area,
                    centroid: c.centroid(),
                    channel: c.channel,
                })
                .collect();
            sections.push(Section {
                name: s.name.clone(),
                length: s.length,
                steps: if s.rigid { 1 } else { s.steps },
                rigid: s.rigid,
                k_se,
                k_bt,
                c_se,
                c_bt,
                line_mass,
                line_force,
                line_moment,
                chambers,
                s_start,
            });
            s_start += s.length;
        }
        let length = spec.length();
        // Force scale: the softest bending stiffness over L^2 (deflects the tip by ~L).
        let ei_min = sections
            .iter()
            .filter(|s| !s.rigid)
            .map(|s| s.k_bt[0][0].min(s.k_bt[1][1]))
            .fold(f64::INFINITY, f64::min);
        let force_scale = if ei_min.is_finite() {
            ei_min / (length * length)
        } else {
            1.0
        };
        Ok(Rod {
            n_channels: spec.n_channels(),
            length,
            base_position: spec.mounting.base_position,
            base_rotation: spec.mounting.base_rotation,
            gravity: spec.mounting.gravity,
            force_scale,
            sections,
            spec,
        })
    }

    /// Total mass of the rod (without the tip body), kg.
    pub fn mass(&self) -> f64 {
        self.sections.iter().map(|s| s.line_mass * s.length).sum()
    }

    pub fn check_pressures(&self, pressures: &[f64]) -> Result<()> {
        validate_pressures(pressures, self.n_channels)
    }
}
