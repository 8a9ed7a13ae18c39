//! The design in SI units, as the Python layer hands it over (or as Rust users build it).
//! `DesignSpec::validate` checks every rule a design must satisfy and names the offending
//! field; `crate::rod::Rod::new` only accepts validated specs.

pub mod obstacle;
pub mod pcc;

use crate::error::{Result, SoftrodError};
use serde::{Deserialize, Serialize};

/// One standard atmosphere in Pa: the lowest meaningful gauge pressure is -1 atm (vacuum).
pub const ATMOSPHERE: f64 = 101_325.0;

/// Linear elastic material, SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus E in Pa.
    pub youngs_modulus: f64,
    /// Shear modulus G in Pa.
    pub shear_modulus: f64,
    /// Mass density in kg/m^3.
    pub density: f64,
}

/// A pressure chamber running the full length of its section, sealed at both ends.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChamberSpec {
    /// Effective pressurised area in m^2.
    pub area: f64,
    /// Radius in m of the circular hole it leaves in the material (for A_m and I);
    /// `None` means a circle of the same area.
    #[serde(default)]
    pub radius: Option<f64>,
    /// Centroid distance from the centreline in m.
    pub distance: f64,
    /// Centroid angle from d1 towards d2 in rad.
    pub angle: f64,
    /// Pressure channel index.
    pub channel: usize,
    /// Centroid distance at the section's end in m (a tapered section; `None`: `distance`
    /// all along). The distance varies linearly in s.
    #[serde(default)]
    pub distance_end: Option<f64>,
    /// Hole radius at the section's end in m (a tapered section; `None`: the start radius
    /// all along). The radius varies linearly in s and the pressurised area with its square.
    #[serde(default)]
    pub radius_end: Option<f64>,
}

impl ChamberSpec {
    /// Radius of the hole in the cross-section.
    pub fn hole_radius(&self) -> f64 {
        self.radius
            .unwrap_or_else(|| (self.area / std::f64::consts::PI).sqrt())
    }
    /// Centroid in body coordinates (d1, d2).
    pub fn centroid(&self) -> [f64; 2] {
        [
            self.distance * self.angle.cos(),
            self.distance * self.angle.sin(),
        ]
    }
}

/// A tendon routed through a section (Rucker and Webster, "Statics and dynamics of continuum
/// robots with general tendon routing and external loading", IEEE T-RO 27(6), 2011). A tendon
/// runs from the base to the end of the last section that lists it, where it is attached;
/// every elastic section before that lists it too (its routing there). Its offset in the
/// cross-section is (distance cos angle, distance sin angle) in (d1, d2), with distance and
/// angle linear in s along the section (`*_end`: the values at the section's end; a helix
/// has a changing angle). Frictionless: the tension is the same all along.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TendonSpec {
    /// Tension channel index (the input `tensions[channel]`).
    pub channel: usize,
    /// Distance of the tendon from the centreline in m.
    pub distance: f64,
    /// Angle from d1 towards d2 in rad.
    pub angle: f64,
    #[serde(default)]
    pub distance_end: Option<f64>,
    #[serde(default)]
    pub angle_end: Option<f64>,
}

impl TendonSpec {
    /// (distance, angle) at the start and the end of a section.
    pub fn ends(&self) -> ([f64; 2], [f64; 2]) {
        (
            [self.distance, self.distance_end.unwrap_or(self.distance)],
            [self.angle, self.angle_end.unwrap_or(self.angle)],
        )
    }
}

/// The frame a tip or line load is given in: fixed in the world (a dead load) or in the
/// body frame (d1, d2, d3) at its point of action (a follower load, which turns with the rod).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Frame {
    #[default]
    World,
    Body,
}

fn e3() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// The reference (stress-free) strains of a section: precurvature u* (bending about d1, d2
/// and twist, 1/m) and pre-strain v* (shear, shear, stretch), body frame. The laws act on
/// the strains relative to them (docs/scope.md, "Reference shape"). Constant, or a table in
/// s interpolated by a not-a-knot cubic spline (C2, so RK4 stays fourth order).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSpec {
    /// Constant u*, 1/m.
    #[serde(default)]
    pub curvature: [f64; 3],
    /// Constant v* (default (0, 0, 1): unsheared, unstretched).
    #[serde(default = "e3")]
    pub strain: [f64; 3],
    /// Or: u* and v* at arc lengths from the section's start (0 ... length).
    #[serde(default)]
    pub table: Option<ReferenceTable>,
}

impl Default for ReferenceSpec {
    fn default() -> Self {
        ReferenceSpec {
            curvature: [0.0; 3],
            strain: e3(),
            table: None,
        }
    }
}

impl ReferenceSpec {
    /// The straight, unstrained reference of the plain rod.
    pub fn is_straight(&self) -> bool {
        *self == ReferenceSpec::default()
    }
}

/// Reference strains tabulated along a section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceTable {
    /// Arc lengths from the section's start, m: strictly increasing from 0 to its length.
    pub s: Vec<f64>,
    /// u* at each s, 1/m.
    pub curvature: Vec<[f64; 3]>,
    /// v* at each s.
    pub strain: Vec<[f64; 3]>,
}

/// Stiffnesses given directly instead of from geometry (paper 004 style). Any value left
/// out is computed from the geometry and material.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StiffnessSpec {
    /// Extensional stiffness EA in N.
    #[serde(default)]
    pub ea: Option<f64>,
    /// Shear stiffness GA in N.
    #[serde(default)]
    pub ga: Option<f64>,
    /// Bending stiffness about d1, E I_11, in N m^2.
    #[serde(default)]
    pub ei1: Option<f64>,
    /// Bending stiffness about d2, E I_22, in N m^2.
    #[serde(default)]
    pub ei2: Option<f64>,
    /// Torsional stiffness GJ in N m^2.
    #[serde(default)]
    pub gj: Option<f64>,
}

fn one() -> f64 {
    1.0
}
fn default_steps() -> usize {
    16
}

/// One section of the chain from base to tip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionSpec {
    pub name: String,
    /// Reference length in m.
    pub length: f64,
    /// A stiff part that only carries mass: its pose is carried straight through.
    #[serde(default)]
    pub rigid: bool,
    /// Outer radius in m (needed unless every stiffness and the mass are given).
    #[serde(default)]
    pub outer_radius: Option<f64>,
    /// Central bore radius in m.
    #[serde(default)]
    pub bore_radius: f64,
    #[serde(default)]
    pub material: Option<MaterialSpec>,
    /// Total mass of the section in kg; overrides density * A_m * length.
    #[serde(default)]
    pub mass: Option<f64>,
    #[serde(default = "one")]
    pub c_s: f64,
    #[serde(default = "one")]
    pub c_e: f64,
    #[serde(default = "one")]
    pub c_b: f64,
    #[serde(default = "one")]
    pub c_t: f64,
    #[serde(default)]
    pub stiffness: StiffnessSpec,
    #[serde(default)]
    pub chambers: Vec<ChamberSpec>,
    /// Fixed RK4 steps in this section.
    #[serde(default = "default_steps")]
    pub steps: usize,
    /// Refinements of the linear law (paper 002 eqs. 16-22, paper 004 eq. 29, paper 001
    /// eq. 13); the default is the plain linear law.
    #[serde(default)]
    pub law: LawSpec,
    /// Paper 004's partitioned cross-section: gives EA and EI and makes the bending
    /// stiffness grow with the stretch.
    #[serde(default)]
    pub partition: Option<PartitionSpec>,
    /// Mass moments of inertia per unit length (rho I_11, rho I_22, rho J), kg m, for
    /// dynamics; `None` derives them (see `crate::rod::Section::rotary_inertia`).
    #[serde(default)]
    pub rotary_inertia: Option<[f64; 3]>,
    /// Kelvin-Voigt damping (paper 000 eq. 8) given as matrices instead of B = tau K:
    /// diagonal of B_se (shear, shear, extension), N s ...
    #[serde(default)]
    pub damping_se: Option<[f64; 3]>,
    /// ... and of B_bt (bending, bending, torsion), N m^2 s. Give both or neither.
    #[serde(default)]
    pub damping_bt: Option<[f64; 3]>,
    /// Reference shape (precurvature, pre-strain); straight when left out.
    #[serde(default)]
    pub reference: ReferenceSpec,
    /// Outer radius at the section's end in m: a tapered section (cone, tentacle) whose
    /// outer radius varies linearly from `outer_radius`; stiffness, weight and pressure
    /// terms follow s.
    #[serde(default)]
    pub outer_radius_end: Option<f64>,
    /// Tendons routed through this section.
    #[serde(default)]
    pub tendons: Vec<TendonSpec>,
}

/// Axial (stretch) law of a section.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum AxialSpec {
    /// n_m3 = k_e (v3 - 1), k_e = c_e EA.
    #[default]
    Linear,
    /// Ogden-type energy of paper 002 eq. 16 in the stretch lambda = |v|, with k_e = c_e EA
    /// (eq. 17) and exponent alpha.
    Ogden { alpha: f64 },
    /// A force-dependent extensional stiffness EA(F) (paper 004 Sec. 3.1), F the material
    /// axial force: monotone cubic interpolation of the table, constant beyond its ends.
    Table {
        force: Vec<f64>,
        stiffness: Vec<f64>,
    },
}

/// Chamber swelling, paper 002 eq. 22: r_p(p) = r_p (1 + c_p p / p_ref).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwellingSpec {
    pub c_p: f64,
    /// Reference pressure p_ref in Pa.
    pub p_ref: f64,
}

/// Constitutive refinements of one section.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LawSpec {
    #[serde(default)]
    pub axial: AxialSpec,
    /// Manufacturing offset rho_off of every chamber centroid (paper 002 eq. 21), in the
    /// body frame (d1, d2), m.
    #[serde(default)]
    pub chamber_offset: [f64; 2],
    #[serde(default)]
    pub swelling: Option<SwellingSpec>,
    /// Bending stiffness proportional to the local stretch v3 (paper 004 eq. 29, L_c/L_c0).
    #[serde(default)]
    pub stretch_bending: bool,
    /// Scale EA, EI_1, EI_2 by the per-solve factors sigma(p) (paper 001 eq. 13).
    #[serde(default)]
    pub stiffness_map: bool,
}

impl LawSpec {
    pub fn is_linear(&self) -> bool {
        *self == LawSpec::default()
    }
}

/// Paper 004's partition of the cross-section into 2j + 1 parts (eqs. 13-15): j parts of
/// stiffness E_I on radius r_I (chambers), j of E_II on r_II, a central one of E_III.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartitionSpec {
    pub j: u32,
    /// Extensional stiffness of one chamber part, N.
    pub e_i: f64,
    /// Radius of the circle of chamber-part centres, m.
    pub r_i: f64,
    #[serde(default)]
    pub e_ii: f64,
    #[serde(default)]
    pub r_ii: f64,
    #[serde(default)]
    pub e_iii: f64,
}

impl PartitionSpec {
    /// E = j (E_I + E_II) + E_III, N (eq. 23).
    pub fn extensional(&self) -> f64 {
        self.j as f64 * (self.e_i + self.e_ii) + self.e_iii
    }
    /// B at stretch 1: (j/2)(E_I r_I^2 + E_II r_II^2), N m^2 (eq. 29).
    pub fn bending(&self) -> f64 {
        0.5 * self.j as f64 * (self.e_i * self.r_i * self.r_i + self.e_ii * self.r_ii * self.r_ii)
    }
}

/// Base pose and gravity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountingSpec {
    /// Base position in the world frame, m.
    #[serde(default)]
    pub base_position: [f64; 3],
    /// Base rotation as rows of the matrix [d1 d2 d3] (columns are the directors in world
    /// coordinates).
    pub base_rotation: [[f64; 3]; 3],
    /// Gravity vector in the world frame, m/s^2.
    pub gravity: [f64; 3],
}

/// Rigid tip body and tip loads (world frame, or the tip's body frame: `frame`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TipSpec {
    /// Mass of a rigid body fixed to the tip, kg.
    #[serde(default)]
    pub mass: f64,
    /// Its centre of mass in the tip frame (d1, d2, d3), m.
    #[serde(default)]
    pub com_offset: [f64; 3],
    /// Force at the tip, N (in `frame`).
    #[serde(default)]
    pub force: [f64; 3],
    /// Moment at the tip, N m (in `frame`).
    #[serde(default)]
    pub moment: [f64; 3],
    /// Principal moments of inertia of the tip body about its centre of mass, along the
    /// tip frame's axes (d1, d2, d3), kg m^2 (dynamics only).
    #[serde(default)]
    pub inertia: [f64; 3],
    /// Frame of `force` and `moment`: world (dead loads) or the tip's body frame (follower
    /// loads).
    #[serde(default)]
    pub frame: Frame,
}

/// Settings of the dynamic model (paper 000 eq. 8 and Sec. III-A).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSpec {
    /// Kelvin-Voigt damping time tau, s: B_se = tau K_se and B_bt = tau K_bt wherever a
    /// section gives no damping matrices (paper 000 eq. 8; 0.19 s for its arm).
    #[serde(default)]
    pub damping_time: f64,
    /// First-order lag between commanded and chamber pressure, s (0: none).
    #[serde(default)]
    pub pressure_time_constant: f64,
    /// Largest rate of change of a chamber pressure, Pa/s (`None`: unlimited; paper 000's
    /// regulators: about 3 kPa/s).
    #[serde(default)]
    pub pressure_rate_limit: Option<f64>,
}

impl DynamicsSpec {
    /// Advance chamber pressures by one step of dt towards the commands: a first-order lag
    /// with time constant T (exact for a command held over the step), then the rate limit
    /// (paper 000 Sec. III-A). The rod's dynamics and the PCC model both use this supply, so
    /// both models see the same pressures.
    pub fn advance_supply(&self, dt: f64, pressures: &mut [f64], command: &[f64]) {
        for (p, &c) in pressures.iter_mut().zip(command) {
            let target = if self.pressure_time_constant > 0.0 {
                c + (*p - c) * (-dt / self.pressure_time_constant).exp()
            } else {
                c
            };
            let step = match self.pressure_rate_limit {
                Some(rate) => (target - *p).clamp(-rate * dt, rate * dt),
                None => target - *p,
            };
            *p += step;
        }
    }
}

/// Distributed line load on one section: dead (world frame) or follower (body frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LineLoadSpec {
    pub section: usize,
    #[serde(default)]
    pub frame: Frame,
    /// Force per unit reference length, N/m.
    #[serde(default)]
    pub force_per_length: [f64; 3],
    /// Moment per unit reference length, N m/m.
    #[serde(default)]
    pub moment_per_length: [f64; 3],
}

/// What the actuator is built and validated for (design file `[operating_range]`). Solves
/// outside it are refused or warned about (`crate::validity::check_operating_range`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatingRangeSpec {
    /// Lowest and highest gauge pressure of every channel, Pa (`None`: not stated).
    #[serde(default)]
    pub pressure: Option<[f64; 2]>,
    /// Lowest and highest tension of every tendon channel, N (`None`: not stated).
    #[serde(default)]
    pub tension: Option<[f64; 2]>,
}

/// A complete design in SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignSpec {
    pub name: String,
    pub mounting: MountingSpec,
    pub sections: Vec<SectionSpec>,
    #[serde(default)]
    pub tip: TipSpec,
    #[serde(default)]
    pub loads: Vec<LineLoadSpec>,
    #[serde(default)]
    pub dynamics: DynamicsSpec,
    /// Parameters of the piecewise-constant-curvature model (paper 003); `None` derives
    /// them from the rod's stiffnesses (see `crate::pcc`).
    #[serde(default)]
    pub pcc: Option<pcc::PccSpec>,
    /// The pressures the actuator is built for; `None`: no range is known.
    #[serde(default)]
    pub operating_range: Option<OperatingRangeSpec>,
    /// Rigid obstacles the rod may touch (`crate::contact`).
    #[serde(default)]
    pub obstacles: Vec<obstacle::ObstacleSpec>,
}

fn finite(field: &str, x: f64) -> Result<()> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(SoftrodError::invalid(field, x, "must be a finite number"))
    }
}

fn positive(field: &str, x: f64) -> Result<()> {
    finite(field, x)?;
    if x > 0.0 {
        Ok(())
    } else {
        Err(SoftrodError::invalid(field, x, "must be > 0"))
    }
}

fn non_negative(field: &str, x: f64) -> Result<()> {
    finite(field, x)?;
    if x >= 0.0 {
        Ok(())
    } else {
        Err(SoftrodError::invalid(field, x, "must be >= 0"))
    }
}

fn finite3(field: &str, v: &[f64; 3]) -> Result<()> {
    finite_each(field, v)
}

/// Every entry finite; the field name `field[i]` is formatted only for an error (these
/// checks run at every time step: formatting each name cost more than the check).
fn finite_each(field: &str, xs: &[f64]) -> Result<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(i) => finite(&format!("{field}[{i}]"), xs[i]),
        None => Ok(()),
    }
}

/// Relative slack in the geometric containment checks, so that a chamber drawn exactly
/// tangent to the outer wall is accepted despite round-off in unit conversion.
pub(crate) const GEOMETRY_SLACK: f64 = 1e-9;

impl MaterialSpec {
    fn validate(&self, field: &str) -> Result<()> {
        positive(&format!("{field}.E"), self.youngs_modulus)?;
        positive(&format!("{field}.G"), self.shear_modulus)?;
        positive(&format!("{field}.density"), self.density)?;
        // nu = E/(2G) - 1 must lie in (-1, 0.5] for a stable isotropic solid.
        let nu = self.youngs_modulus / (2.0 * self.shear_modulus) - 1.0;
        if !(nu > -1.0 && nu <= 0.5 + 1e-12) {
            return Err(SoftrodError::invalid(
                format!("{field}.poisson"),
                format!("{nu:.6}"),
                "Poisson's ratio E/(2G) - 1 must lie in (-1, 0.5]",
            ));
        }
        Ok(())
    }
}

impl SectionSpec {
    /// Centroid of chamber k in (d1, d2) including the section's chamber offset, m.
    pub fn chamber_centroid(&self, k: usize) -> [f64; 2] {
        let c = self.chambers[k].centroid();
        let o = self.law.chamber_offset;
        [c[0] + o[0], c[1] + o[1]]
    }

    /// EA and EI the section is given directly (or by its partition), N and N m^2.
    pub fn given_stiffness(&self) -> StiffnessSpec {
        let mut st = self.stiffness;
        if let Some(p) = &self.partition {
            st.ea = Some(p.extensional());
            st.ei1 = Some(p.bending());
            st.ei2 = Some(p.bending());
        }
        st
    }

    /// Bending stiffness proportional to the stretch (set, or implied by a partition).
    pub fn stretch_bending(&self) -> bool {
        self.law.stretch_bending || self.partition.is_some()
    }

    fn validate_law(&self, i: usize) -> Result<()> {
        let f = |k: &str| format!("sections[{i}].{k}");
        if self.rigid && (!self.law.is_linear() || self.partition.is_some()) {
            // Name the table the design file has: [sections.law], else [sections.partition].
            return Err(SoftrodError::invalid(
                f(if self.law.is_linear() {
                    "partition"
                } else {
                    "law"
                }),
                "set",
                "a rigid section has no constitutive law (remove law/partition or make it elastic)",
            ));
        }
        match &self.law.axial {
            AxialSpec::Linear => {}
            AxialSpec::Ogden { alpha } => {
                finite(&f("law.alpha"), *alpha)?;
                if !(*alpha > 0.0 && *alpha <= 100.0) {
                    return Err(SoftrodError::invalid(
                        f("law.alpha"),
                        alpha,
                        "the Ogden exponent must lie in (0, 100] (paper 002 eq. 16)",
                    ));
                }
            }
            AxialSpec::Table { force, stiffness } => {
                if force.len() < 2 || force.len() != stiffness.len() {
                    return Err(SoftrodError::invalid(
                        f("law.axial_force"),
                        format!("{} forces, {} stiffnesses", force.len(), stiffness.len()),
                        "an EA(F) table needs at least 2 points and as many stiffnesses as forces",
                    ));
                }
                for (k, x) in force.iter().enumerate() {
                    finite(&f(&format!("law.axial_force[{k}]")), *x)?;
                    if k > 0 && *x <= force[k - 1] {
                        return Err(SoftrodError::invalid(
                            f(&format!("law.axial_force[{k}]")),
                            x,
                            "table forces must increase strictly",
                        ));
                    }
                }
                for (k, x) in stiffness.iter().enumerate() {
                    positive(&f(&format!("law.axial_stiffness[{k}]")), *x)?;
                }
            }
        }
        for (k, o) in self.law.chamber_offset.iter().enumerate() {
            finite(&f(&format!("law.chamber_offset[{k}]")), *o)?;
        }
        if let Some(sw) = &self.law.swelling {
            finite(&f("law.c_p"), sw.c_p)?;
            positive(&f("law.p_ref"), sw.p_ref)?;
            if self.chambers.is_empty() {
                return Err(SoftrodError::invalid(
                    f("law.c_p"),
                    "set",
                    "chamber swelling needs chambers in this section",
                ));
            }
        }
        if let Some(p) = &self.partition {
            if p.j < 3 {
                return Err(SoftrodError::invalid(
                    f("partition.j"),
                    p.j,
                    "must be >= 3 (paper 004 eqs. 20 and 28 hold for j >= 3)",
                ));
            }
            positive(&f("partition.E_I"), p.e_i)?;
            positive(&f("partition.r_I"), p.r_i)?;
            non_negative(&f("partition.E_II"), p.e_ii)?;
            non_negative(&f("partition.r_II"), p.r_ii)?;
            non_negative(&f("partition.E_III"), p.e_iii)?;
            let st = &self.stiffness;
            if st.ea.is_some() || st.ei1.is_some() || st.ei2.is_some() {
                return Err(SoftrodError::invalid(
                    f("partition"),
                    "set",
                    "the partition gives EA and EI; do not also give EA, EI, EI1 or EI2",
                ));
            }
            if matches!(self.law.axial, AxialSpec::Table { .. }) {
                return Err(SoftrodError::invalid(
                    f("law.axial"),
                    "table",
                    "an EA(F) table replaces the partition's E; use one or the other",
                ));
            }
        }
        Ok(())
    }

    fn validate(&self, i: usize) -> Result<()> {
        let f = |k: &str| format!("sections[{i}].{k}");
        if self.name.trim().is_empty() {
            return Err(SoftrodError::invalid(f("name"), "''", "must not be empty"));
        }
        positive(&f("length"), self.length)?;
        non_negative(&f("bore_radius"), self.bore_radius)?;
        for (k, c) in [
            ("c_s", self.c_s),
            ("c_e", self.c_e),
            ("c_b", self.c_b),
            ("c_t", self.c_t),
        ] {
            positive(&f(k), c)?;
        }
        if let Some(m) = self.mass {
            non_negative(&f("mass"), m)?;
        }
        if let Some(j) = &self.rotary_inertia {
            for (k, x) in j.iter().enumerate() {
                non_negative(&f(&format!("rotary_inertia[{k}]")), *x)?;
            }
        }
        match (&self.damping_se, &self.damping_bt) {
            (Some(se), Some(bt)) => {
                for (k, x) in se.iter().enumerate() {
                    non_negative(&f(&format!("damping_se[{k}]")), *x)?;
                }
                for (k, x) in bt.iter().enumerate() {
                    non_negative(&f(&format!("damping_bt[{k}]")), *x)?;
                }
            }
            (None, None) => {}
            (Some(_), None) => {
                return Err(SoftrodError::invalid(
                    f("damping_bt"),
                    "missing",
                    "give damping_se and damping_bt together (or neither, for B = tau K)",
                ))
            }
            (None, Some(_)) => {
                return Err(SoftrodError::invalid(
                    f("damping_se"),
                    "missing",
                    "give damping_se and damping_bt together (or neither, for B = tau K)",
                ))
            }
        }
        if let Some(mat) = &self.material {
            mat.validate(&f("material"))?;
        }
        self.validate_law(i)?;
        let st = &self.given_stiffness();
        for (k, v) in [
            ("EA", st.ea),
            ("GA", st.ga),
            ("EI1", st.ei1),
            ("EI2", st.ei2),
            ("GJ", st.gj),
        ] {
            if let Some(v) = v {
                positive(&f(k), v)?;
            }
        }
        if let Some(ro) = self.outer_radius {
            positive(&f("outer_radius"), ro)?;
            if self.bore_radius >= ro {
                return Err(SoftrodError::invalid(
                    f("bore_radius"),
                    self.bore_radius,
                    format!("must be smaller than outer_radius = {ro}"),
                ));
            }
        }
        if self.rigid && !self.chambers.is_empty() {
            return Err(SoftrodError::invalid(
                f("chambers"),
                self.chambers.len(),
                "a rigid section cannot hold pressure chambers (make it elastic or move the chambers)",
            ));
        }
        // What must be known to build the section: its weight, and (if elastic) all five
        // stiffnesses, from geometry + material or given directly.
        let all_stiffness_given = st.ea.is_some()
            && st.ga.is_some()
            && st.ei1.is_some()
            && st.ei2.is_some()
            && st.gj.is_some();
        let has_geometry = self.outer_radius.is_some() && self.material.is_some();
        if !self.rigid && !has_geometry && !all_stiffness_given {
            return Err(SoftrodError::invalid(
                f("outer_radius"),
                "missing",
                "an elastic section needs outer_radius and material, or all of EA, GA, EI1, EI2, GJ",
            ));
        }
        if self.mass.is_none() && !has_geometry {
            return Err(SoftrodError::invalid(
                f("mass"),
                "missing",
                "give mass, or outer_radius and material so the weight can be computed",
            ));
        }
        for (k, c) in self.chambers.iter().enumerate() {
            let g = |key: &str| format!("sections[{i}].chambers[{k}].{key}");
            positive(&g("area"), c.area)?;
            if let Some(r) = c.radius {
                positive(&g("radius"), r)?;
            }
            non_negative(&g("distance"), c.distance)?;
            finite(&g("angle"), c.angle)?;
            if let Some(d) = c.distance_end {
                non_negative(&g("distance_end"), d)?;
            }
            if let Some(r) = c.radius_end {
                positive(&g("radius_end"), r)?;
            }
            // Geometry at the relative position t along the section (0: start, 1: end):
            // distances and radii are linear in t, so containment (convex in t) holds
            // everywhere if it holds at both ends, and the squared clearances to the bore and
            // between chambers are quadratics in t whose minimum is found exactly.
            let at = |k: usize, t: f64| -> ([f64; 2], f64) {
                let ([d0, d1], [r0, r1]) = self.chamber_ends(k);
                let d = d0 + t * (d1 - d0);
                let a = self.chambers[k].angle;
                let o = self.law.chamber_offset;
                ([o[0] + d * a.cos(), o[1] + d * a.sin()], r0 + t * (r1 - r0))
            };
            let ends = |t: f64| {
                if t == 0.0 {
                    ""
                } else {
                    " at the section's end"
                }
            };
            for t in [0.0, 1.0] {
                if t == 1.0 && !self.is_tapered() {
                    break;
                }
                let ([cx, cy], r) = at(k, t);
                let dist = cx.hypot(cy);
                let outer = self
                    .outer_radius
                    .map(|ro| ro + t * (self.outer_radius_end.unwrap_or(ro) - ro));
                let key = if t == 0.0 { "distance" } else { "distance_end" };
                if let Some(ro) = outer {
                    if dist + r > ro * (1.0 + GEOMETRY_SLACK) {
                        return Err(SoftrodError::invalid(
                            g(key),
                            c.distance_end.filter(|_| t == 1.0).unwrap_or(c.distance),
                            format!(
                                "chamber lies outside the section{}: distance (with chamber_offset) + radius = {:.6e} m exceeds outer_radius = {ro:.6e} m",
                                ends(t),
                                dist + r
                            ),
                        ));
                    }
                }
            }
            if self.bore_radius > 0.0 {
                let (t, q) = quadratic_min(|t| {
                    let ([cx, cy], r) = at(k, t);
                    cx * cx + cy * cy - (r + self.bore_radius).powi(2)
                });
                let ([cx, cy], r) = at(k, t);
                let dist = cx.hypot(cy);
                if q < 0.0 && dist - r < self.bore_radius * (1.0 - GEOMETRY_SLACK) {
                    return Err(SoftrodError::invalid(
                        g("distance"),
                        c.distance,
                        format!(
                            "chamber overlaps the bore{}: distance (with chamber_offset) - radius = {:.6e} m is less than bore_radius = {:.6e} m",
                            if t == 0.0 { String::new() } else { format!(" at {:.4} of the section's length", t) },
                            dist - r,
                            self.bore_radius
                        ),
                    ));
                }
            }
            for j in 0..k {
                let (t, _) = quadratic_min(|t| {
                    let ((a, ra), (b, rb)) = (at(k, t), at(j, t));
                    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) - (ra + rb).powi(2)
                });
                let ((a, ra), (b, rb)) = (at(k, t), at(j, t));
                let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
                let min = ra + rb;
                if d < min * (1.0 - GEOMETRY_SLACK) {
                    return Err(SoftrodError::invalid(
                        g("angle"),
                        c.angle,
                        format!(
                            "chamber overlaps chambers[{j}]{}: centre distance {d:.6e} m is less than the sum of radii {min:.6e} m",
                            if t == 0.0 { String::new() } else { format!(" at {:.4} of the section's length", t) },
                        ),
                    ));
                }
            }
        }
        self.validate_reference(i)?;
        self.validate_taper(i)?;
        self.validate_tendons(i)?;
        Ok(())
    }

    /// The section's properties change along s (taper, chamber or reference tables).
    pub fn is_varying(&self) -> bool {
        self.outer_radius_end.is_some()
            || self.reference.table.is_some()
            || self
                .chambers
                .iter()
                .any(|c| c.distance_end.is_some() || c.radius_end.is_some())
    }

    /// The cross-section changes along s (outer radius or chambers).
    pub fn is_tapered(&self) -> bool {
        self.outer_radius_end.is_some()
            || self
                .chambers
                .iter()
                .any(|c| c.distance_end.is_some() || c.radius_end.is_some())
    }

    fn validate_reference(&self, i: usize) -> Result<()> {
        let f = |k: &str| format!("sections[{i}].reference.{k}");
        let r = &self.reference;
        if r.is_straight() {
            return Ok(());
        }
        if self.rigid {
            return Err(SoftrodError::invalid(
                format!("sections[{i}].reference"),
                "set",
                "a rigid section is carried straight through; give the reference shape to an elastic section",
            ));
        }
        finite3(&f("curvature"), &r.curvature)?;
        finite3(&f("strain"), &r.strain)?;
        let Some(t) = &r.table else {
            return check_reference_stretch(&f("strain"), &r.strain);
        };
        if r.curvature != [0.0; 3] || r.strain != e3() {
            return Err(SoftrodError::invalid(
                f("table"),
                "set",
                "give a constant curvature/strain or a table, not both",
            ));
        }
        let n = t.s.len();
        if n < 2 || t.curvature.len() != n || t.strain.len() != n {
            return Err(SoftrodError::invalid(
                f("table.s"),
                format!(
                    "{n} arc lengths, {} curvatures, {} strains",
                    t.curvature.len(),
                    t.strain.len()
                ),
                "a reference table needs at least 2 points and one curvature and one strain per point",
            ));
        }
        for (k, x) in t.s.iter().enumerate() {
            finite(&f(&format!("table.s[{k}]")), *x)?;
            if k > 0 && *x <= t.s[k - 1] {
                return Err(SoftrodError::invalid(
                    f(&format!("table.s[{k}]")),
                    x,
                    "table arc lengths must increase strictly",
                ));
            }
            finite3(&f(&format!("table.curvature[{k}]")), &t.curvature[k])?;
            finite3(&f(&format!("table.strain[{k}]")), &t.strain[k])?;
            check_reference_stretch(&f(&format!("table.strain[{k}]")), &t.strain[k])?;
        }
        let slack = GEOMETRY_SLACK * self.length;
        if t.s[0].abs() > slack || (t.s[n - 1] - self.length).abs() > slack {
            return Err(SoftrodError::invalid(
                f("table.s"),
                format!("[{}, ..., {}] m", t.s[0], t.s[n - 1]),
                format!(
                    "must run from 0 to the section's length {} m (arc length from the section's start)",
                    self.length
                ),
            ));
        }
        Ok(())
    }

    fn validate_taper(&self, i: usize) -> Result<()> {
        let f = |k: &str| format!("sections[{i}].{k}");
        if !self.is_tapered() {
            return Ok(());
        }
        let key = if self.outer_radius_end.is_some() {
            f("outer_radius_end")
        } else {
            f("chambers")
        };
        if self.rigid {
            return Err(SoftrodError::invalid(
                key,
                "set",
                "a rigid section has no cross-section law to taper",
            ));
        }
        if matches!(self.law.axial, AxialSpec::Ogden { .. }) {
            return Err(SoftrodError::invalid(
                key,
                "set",
                "a tapered cross-section with axial = \"ogden\" is not supported (the carried stretch assumes a uniform section); use the linear or table law, or split the section",
            ));
        }
        if let Some(re) = self.outer_radius_end {
            positive(&f("outer_radius_end"), re)?;
            let st = self.given_stiffness();
            let given = st.ea.is_some()
                || st.ga.is_some()
                || st.ei1.is_some()
                || st.ei2.is_some()
                || st.gj.is_some()
                || matches!(self.law.axial, AxialSpec::Table { .. });
            if self.outer_radius.is_none() || self.material.is_none() || given {
                return Err(SoftrodError::invalid(
                    f("outer_radius_end"),
                    re,
                    "a tapered section takes its stiffness from its geometry: give outer_radius and material, and no EA, GA, EI, GJ, partition or EA(F) table",
                ));
            }
            if self.mass.is_some() {
                return Err(SoftrodError::invalid(
                    f("mass"),
                    "set",
                    "a tapered section's weight follows its cross-section (density times area): leave mass out",
                ));
            }
            if self.bore_radius >= re {
                return Err(SoftrodError::invalid(
                    f("bore_radius"),
                    self.bore_radius,
                    format!("must be smaller than outer_radius_end = {re}"),
                ));
            }
        }
        for (k, c) in self.chambers.iter().enumerate() {
            let g = |key: &str| format!("sections[{i}].chambers[{k}].{key}");
            if let Some(d) = c.distance_end {
                non_negative(&g("distance_end"), d)?;
            }
            if let Some(r) = c.radius_end {
                positive(&g("radius_end"), r)?;
            }
        }
        Ok(())
    }

    fn validate_tendons(&self, i: usize) -> Result<()> {
        if !self.tendons.is_empty() && !matches!(self.law.axial, AxialSpec::Linear) {
            return Err(SoftrodError::invalid(
                format!("sections[{i}].tendons"),
                format!("{} tendons", self.tendons.len()),
                "tendons are supported with the linear axial law (with stretch-dependent bending, swelling, offsets and stiffness maps), not with axial = \"ogden\" or \"table\"",
            ));
        }
        for (k, t) in self.tendons.iter().enumerate() {
            let g = |key: &str| format!("sections[{i}].tendons[{k}].{key}");
            if self.rigid {
                return Err(SoftrodError::invalid(
                    format!("sections[{i}].tendons"),
                    self.tendons.len(),
                    "a rigid section passes every tendon through unchanged: list tendons in elastic sections only",
                ));
            }
            non_negative(&g("distance"), t.distance)?;
            finite(&g("angle"), t.angle)?;
            if let Some(d) = t.distance_end {
                non_negative(&g("distance_end"), d)?;
            }
            if let Some(a) = t.angle_end {
                finite(&g("angle_end"), a)?;
            }
            if let Some(ro) = self.outer_radius {
                let ([d0, d1], _) = t.ends();
                let r1 = self.outer_radius_end.unwrap_or(ro);
                for (d, r, key) in [(d0, ro, "distance"), (d1, r1, "distance_end")] {
                    if d > r * (1.0 + GEOMETRY_SLACK) {
                        return Err(SoftrodError::invalid(
                            g(key),
                            d,
                            format!("the tendon lies outside the section (outer radius {r:.6e} m there)"),
                        ));
                    }
                }
            }
            if self.tendons[..k].iter().any(|o| o.channel == t.channel) {
                return Err(SoftrodError::invalid(
                    g("channel"),
                    t.channel,
                    "a section lists each tendon once (two tendons on one channel would share one tension: give them their own channels)",
                ));
            }
        }
        Ok(())
    }

    /// Chamber `k`'s (distance, hole radius) at the start and end of the section.
    pub fn chamber_ends(&self, k: usize) -> ([f64; 2], [f64; 2]) {
        let c = &self.chambers[k];
        let r = c.hole_radius();
        (
            [c.distance, c.distance_end.unwrap_or(c.distance)],
            [r, c.radius_end.unwrap_or(r)],
        )
    }
}

/// The minimum over t in [0, 1] of a quadratic q (from its values at 0, 1/2 and 1), and where.
fn quadratic_min(q: impl Fn(f64) -> f64) -> (f64, f64) {
    let (q0, qh, q1) = (q(0.0), q(0.5), q(1.0));
    let a = 2.0 * (q1 - 2.0 * qh + q0);
    let b = q1 - q0 - a;
    let mut best = if q1 < q0 { (1.0, q1) } else { (0.0, q0) };
    if a > 0.0 {
        let t = -b / (2.0 * a);
        if t > 0.0 && t < 1.0 {
            let v = q(t);
            if v < best.1 {
                best = (t, v);
            }
        }
    }
    best
}

/// A reference stretch v3* > 0 (a rod of positive length).
fn check_reference_stretch(field: &str, v: &[f64; 3]) -> Result<()> {
    if v[2] > 0.0 {
        Ok(())
    } else {
        Err(SoftrodError::invalid(
            format!("{field}[2]"),
            v[2],
            "the reference stretch v3* must be > 0",
        ))
    }
}

impl DesignSpec {
    /// Number of pressure channels: one past the largest channel index.
    pub fn n_channels(&self) -> usize {
        self.sections
            .iter()
            .flat_map(|s| s.chambers.iter().map(|c| c.channel.saturating_add(1)))
            .max()
            .unwrap_or(0)
    }

    /// Number of tendon (tension) channels: one past the largest tendon channel index.
    pub fn n_tendons(&self) -> usize {
        self.sections
            .iter()
            .flat_map(|s| s.tendons.iter().map(|t| t.channel.saturating_add(1)))
            .max()
            .unwrap_or(0)
    }

    /// Index of the last section that lists tendon `channel` (where it is attached).
    pub fn tendon_end(&self, channel: usize) -> Option<usize> {
        self.sections
            .iter()
            .rposition(|s| s.tendons.iter().any(|t| t.channel == channel))
    }

    /// A load of the design is a follower load (body frame) and not zero.
    pub fn has_follower_line_loads(&self) -> bool {
        self.loads.iter().any(|l| {
            l.frame == Frame::Body
                && (l.force_per_length.iter().any(|x| *x != 0.0)
                    || l.moment_per_length.iter().any(|x| *x != 0.0))
        })
    }

    /// Total reference length in m.
    pub fn length(&self) -> f64 {
        self.sections.iter().map(|s| s.length).sum()
    }

    /// The size limits of `crate::validity` (channels, sections, chambers, steps, loads,
    /// tables), checked before anything is allocated or looped over by these sizes.
    pub fn check_sizes(&self) -> Result<()> {
        use crate::validity::{
            MAX_CHAMBERS_PER_SECTION, MAX_CHANNELS, MAX_LINE_LOADS, MAX_SECTIONS,
            MAX_STEPS_PER_SECTION, MAX_TABLE_POINTS, MAX_TENDONS, MAX_TOTAL_STEPS,
        };
        if self.sections.len() > MAX_SECTIONS {
            return Err(SoftrodError::invalid(
                "sections",
                format!("{} sections", self.sections.len()),
                format!("a design may have at most {MAX_SECTIONS} sections"),
            ));
        }
        if self.obstacles.len() > obstacle::MAX_OBSTACLES {
            return Err(SoftrodError::invalid(
                "obstacles",
                format!("{} obstacles", self.obstacles.len()),
                format!(
                    "a design may have at most {} obstacles",
                    obstacle::MAX_OBSTACLES
                ),
            ));
        }
        if self.loads.len() > MAX_LINE_LOADS {
            return Err(SoftrodError::invalid(
                "loads",
                format!("{} loads", self.loads.len()),
                format!("a design may have at most {MAX_LINE_LOADS} line loads"),
            ));
        }
        let mut total_steps: usize = 0;
        for (i, s) in self.sections.iter().enumerate() {
            if s.chambers.len() > MAX_CHAMBERS_PER_SECTION {
                return Err(SoftrodError::invalid(
                    format!("sections[{i}].chambers"),
                    format!("{} chambers", s.chambers.len()),
                    format!("a section may have at most {MAX_CHAMBERS_PER_SECTION} chambers"),
                ));
            }
            for (k, c) in s.chambers.iter().enumerate() {
                if c.channel >= MAX_CHANNELS {
                    return Err(SoftrodError::invalid(
                        format!("sections[{i}].chambers[{k}].channel"),
                        c.channel,
                        format!("channel indices must lie in 0..{MAX_CHANNELS} (at most {MAX_CHANNELS} pressure channels)"),
                    ));
                }
            }
            if s.tendons.len() > MAX_TENDONS {
                return Err(SoftrodError::invalid(
                    format!("sections[{i}].tendons"),
                    format!("{} tendons", s.tendons.len()),
                    format!("a section may have at most {MAX_TENDONS} tendons"),
                ));
            }
            for (k, t) in s.tendons.iter().enumerate() {
                if t.channel >= MAX_TENDONS {
                    return Err(SoftrodError::invalid(
                        format!("sections[{i}].tendons[{k}].channel"),
                        t.channel,
                        format!("tendon channel indices must lie in 0..{MAX_TENDONS} (at most {MAX_TENDONS} tendons)"),
                    ));
                }
            }
            if let Some(t) = &s.reference.table {
                let n = t.s.len().max(t.curvature.len()).max(t.strain.len());
                if n > MAX_TABLE_POINTS {
                    return Err(SoftrodError::invalid(
                        format!("sections[{i}].reference.table.s"),
                        format!("{n} points"),
                        format!("a reference table may have at most {MAX_TABLE_POINTS} points"),
                    ));
                }
            }
            if s.steps == 0 || s.steps > MAX_STEPS_PER_SECTION {
                return Err(SoftrodError::invalid(
                    format!("sections[{i}].steps"),
                    s.steps,
                    format!("must be in 1..={MAX_STEPS_PER_SECTION}"),
                ));
            }
            total_steps = total_steps.saturating_add(s.steps);
            if let AxialSpec::Table { force, stiffness } = &s.law.axial {
                let n = force.len().max(stiffness.len());
                if n > MAX_TABLE_POINTS {
                    return Err(SoftrodError::invalid(
                        format!("sections[{i}].law.axial_force"),
                        format!("{n} points"),
                        format!("an EA(F) table may have at most {MAX_TABLE_POINTS} points"),
                    ));
                }
            }
        }
        if total_steps > MAX_TOTAL_STEPS {
            return Err(SoftrodError::invalid(
                "sections.steps",
                total_steps,
                format!("the rod may have at most {MAX_TOTAL_STEPS} integration steps in all"),
            ));
        }
        Ok(())
    }

    /// Check every rule; the first broken one is reported with its field path.
    pub fn validate(&self) -> Result<()> {
        self.check_sizes()?;
        if self.sections.is_empty() {
            return Err(SoftrodError::invalid(
                "sections",
                "[]",
                "a design needs at least one section",
            ));
        }
        finite3("mounting.base_position", &self.mounting.base_position)?;
        finite3("mounting.gravity", &self.mounting.gravity)?;
        let r = &self.mounting.base_rotation;
        for (i, row) in r.iter().enumerate() {
            finite3(&format!("mounting.base_rotation[{i}]"), row)?;
        }
        // Orthonormal with det +1, to 1e-9 (a rotation typed with 10 digits passes).
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                if (dot - want).abs() > 1e-9 {
                    return Err(SoftrodError::invalid(
                        "mounting.base_rotation",
                        format!("{r:?}"),
                        "must be a rotation matrix (orthonormal columns, determinant +1)",
                    ));
                }
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if det < 0.0 {
            return Err(SoftrodError::invalid(
                "mounting.base_rotation",
                format!("{r:?}"),
                "must be a proper rotation (determinant +1, not a reflection)",
            ));
        }
        for (i, s) in self.sections.iter().enumerate() {
            s.validate(i)?;
            if self.sections[..i].iter().any(|o| o.name == s.name) {
                return Err(SoftrodError::invalid(
                    format!("sections[{i}].name"),
                    &s.name,
                    "section names must be unique",
                ));
            }
        }
        non_negative("tip.mass", self.tip.mass)?;
        finite3("tip.com_offset", &self.tip.com_offset)?;
        finite3("tip.force", &self.tip.force)?;
        finite3("tip.moment", &self.tip.moment)?;
        for (k, x) in self.tip.inertia.iter().enumerate() {
            non_negative(&format!("tip.inertia[{k}]"), *x)?;
        }
        let dy = &self.dynamics;
        non_negative("dynamics.damping_time", dy.damping_time)?;
        non_negative("dynamics.pressure_time_constant", dy.pressure_time_constant)?;
        if let Some(r) = dy.pressure_rate_limit {
            positive("dynamics.pressure_rate_limit", r)?;
        }
        for (k, l) in self.loads.iter().enumerate() {
            if l.section >= self.sections.len() {
                return Err(SoftrodError::invalid(
                    format!("loads[{k}].section"),
                    l.section,
                    format!("must name one of the {} sections", self.sections.len()),
                ));
            }
            finite3(&format!("loads[{k}].force_per_length"), &l.force_per_length)?;
            finite3(
                &format!("loads[{k}].moment_per_length"),
                &l.moment_per_length,
            )?;
        }
        for (k, o) in self.obstacles.iter().enumerate() {
            o.validate(k)?;
        }
        if let Some(p) = &self.pcc {
            p.validate()?;
        }
        if let Some(r) = &self.operating_range {
            if r.pressure.is_none() && r.tension.is_none() {
                return Err(SoftrodError::invalid(
                    "operating_range",
                    "{}",
                    "must state a pressure range, a tension range or both",
                ));
            }
            if let Some([lo, hi]) = r.pressure {
                finite("operating_range.pressure[0]", lo)?;
                finite("operating_range.pressure[1]", hi)?;
                if lo < -ATMOSPHERE || hi <= lo {
                    return Err(SoftrodError::invalid(
                        "operating_range.pressure",
                        format!("[{lo}, {hi}] Pa"),
                        "must be [low, high] gauge pressures with -101325 Pa <= low < high",
                    ));
                }
            }
            if let Some([lo, hi]) = r.tension {
                finite("operating_range.tension[0]", lo)?;
                finite("operating_range.tension[1]", hi)?;
                if lo < 0.0 || hi <= lo {
                    return Err(SoftrodError::invalid(
                        "operating_range.tension",
                        format!("[{lo}, {hi}] N"),
                        "must be [low, high] tendon tensions with 0 N <= low < high",
                    ));
                }
            }
        }
        let n = self.n_channels();
        let mut used = vec![false; n];
        for s in &self.sections {
            for c in &s.chambers {
                used[c.channel] = true;
            }
        }
        if let Some(missing) = used.iter().position(|u| !u) {
            return Err(SoftrodError::invalid(
                "chambers.channel",
                missing,
                format!("channel indices must be contiguous from 0: channel {missing} is unused but {} channels are declared", n),
            ));
        }
        self.validate_tendon_routes()
    }

    /// Tendon channels numbered 0, 1, ... without gaps, and every tendon routed through
    /// every elastic section from the base to its attachment (a tendon is pulled at the
    /// base: it cannot skip a section).
    fn validate_tendon_routes(&self) -> Result<()> {
        for c in 0..self.n_tendons() {
            let Some(end) = self.tendon_end(c) else {
                return Err(SoftrodError::invalid(
                    "tendons.channel",
                    c,
                    format!(
                        "tendon channels must be contiguous from 0: channel {c} is unused but {} tendon channels are declared",
                        self.n_tendons()
                    ),
                ));
            };
            for (i, s) in self.sections[..end].iter().enumerate() {
                if !s.rigid && !s.tendons.iter().any(|t| t.channel == c) {
                    return Err(SoftrodError::invalid(
                        format!("sections[{i}].tendons"),
                        format!("no tendon on channel {c}"),
                        format!(
                            "tendon {c} is attached at the end of sections[{end}] ({}) and runs from the base: list its routing in every elastic section before that too",
                            self.sections[end].name
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Check a tension vector against the design: right length, finite, >= 0 (a tendon can
/// only pull; a slack tendon has tension 0).
pub fn validate_tensions(tensions: &[f64], n_tendons: usize) -> Result<()> {
    if tensions.len() != n_tendons {
        return Err(SoftrodError::invalid(
            "tensions",
            format!("{} values", tensions.len()),
            format!("the design has {n_tendons} tendons; give one tension (N) per tendon channel"),
        ));
    }
    for (i, &t) in tensions.iter().enumerate() {
        if !t.is_finite() {
            // Formatted only for the error: this runs at every time step.
            return finite(&format!("tensions[{i}]"), t);
        }
        if t < 0.0 {
            return Err(SoftrodError::invalid(
                format!("tensions[{i}]"),
                t,
                "a tendon can only pull: tension must be >= 0 (0 is a slack tendon)",
            ));
        }
    }
    Ok(())
}

/// Check a pressure vector against the design: right length, finite, above vacuum.
pub fn validate_pressures(pressures: &[f64], n_channels: usize) -> Result<()> {
    if pressures.len() != n_channels {
        return Err(SoftrodError::invalid(
            "pressures",
            format!("{} values", pressures.len()),
            format!("the design has {n_channels} pressure channels; give one gauge pressure (Pa) per channel"),
        ));
    }
    for (i, &p) in pressures.iter().enumerate() {
        if !p.is_finite() {
            // Formatted only for the error: this runs at every time step.
            return finite(&format!("pressures[{i}]"), p);
        }
        if p < -ATMOSPHERE {
            return Err(SoftrodError::invalid(
                format!("pressures[{i}]"),
                p,
                "gauge pressure must be >= -101325 Pa (-1 atm, a perfect vacuum)",
            ));
        }
    }
    Ok(())
}
