//! Rigid obstacles of a design (`[[obstacles]]`, docs/contact.md), SI units: their shape and
//! pose, and the stiffness, smoothing length and penetration tolerance of the penalty law
//! (`crate::contact`).

use crate::error::{Result, SoftrodError};
use serde::{Deserialize, Serialize};

/// Shape of an obstacle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObstacleKind {
    /// A half-space: `point` on its surface, `normal` pointing out of the obstacle.
    Plane,
    /// A ball: `center`, `radius`.
    Sphere,
    /// An infinite round cylinder: `point` on its axis, `axis` direction, `radius`.
    Cylinder,
    /// A segment from `start` to `end` swept by a ball of `radius`.
    Capsule,
    /// A rigid triangle mesh: `vertices` (m) and `faces` (vertex indices, counter-clockwise
    /// seen from outside), `crate::mesh`.
    Mesh,
}

impl ObstacleKind {
    pub fn name(self) -> &'static str {
        match self {
            ObstacleKind::Plane => "plane",
            ObstacleKind::Sphere => "sphere",
            ObstacleKind::Cylinder => "cylinder",
            ObstacleKind::Capsule => "capsule",
            ObstacleKind::Mesh => "mesh",
        }
    }

    /// The pose and size fields this kind needs (every other one must be absent).
    fn fields(self) -> &'static [&'static str] {
        match self {
            ObstacleKind::Plane => &["point", "normal"],
            ObstacleKind::Sphere => &["center", "radius"],
            ObstacleKind::Cylinder => &["point", "axis", "radius"],
            ObstacleKind::Capsule => &["start", "end", "radius"],
            ObstacleKind::Mesh => &["vertices", "faces"],
        }
    }
}

/// A rigid obstacle. The penalty law pushes the rod's surface out of it with a force per
/// unit length k * ramp(penetration) along the obstacle's outward normal (`crate::contact`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    pub kind: ObstacleKind,
    /// A point on the plane, or on the cylinder's axis, m.
    #[serde(default)]
    pub point: Option<[f64; 3]>,
    /// The plane's outward normal (normalised when compiled).
    #[serde(default)]
    pub normal: Option<[f64; 3]>,
    /// The sphere's centre, m.
    #[serde(default)]
    pub center: Option<[f64; 3]>,
    /// The cylinder's axis direction (normalised when compiled).
    #[serde(default)]
    pub axis: Option<[f64; 3]>,
    /// The capsule's segment ends, m.
    #[serde(default)]
    pub start: Option<[f64; 3]>,
    #[serde(default)]
    pub end: Option<[f64; 3]>,
    /// Radius of a sphere, cylinder or capsule, m.
    #[serde(default)]
    pub radius: Option<f64>,
    /// A mesh's vertices, m (world frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertices: Option<Vec<[f64; 3]>>,
    /// A mesh's triangles: three indices into `vertices` each, counter-clockwise seen from
    /// outside (`crate::mesh`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub faces: Option<Vec<[usize; 3]>>,
    /// Penalty stiffness k: contact force per unit rod length per metre of penetration,
    /// N/m^2.
    pub stiffness: f64,
    /// Penetration allowed in a solution, m: deeper is an error (`Rule::Penetration`).
    pub tolerance: f64,
    /// Smoothing length eps of the ramp, m (`None`: a tenth of the tolerance).
    #[serde(default)]
    pub smoothing: Option<f64>,
    /// Coulomb friction coefficient (0: frictionless). The free tip's static solve follows
    /// a load path with it (`statics::friction`); the other static solves refuse a
    /// positive coefficient (docs/contact.md, "Friction in the statics", says why).
    #[serde(default)]
    pub friction: f64,
    /// Regularisation velocity of the dynamics' Coulomb law, m/s (`None`: 1 mm/s): below
    /// it friction grows linearly with the slip velocity (docs/contact.md, "Dynamics").
    #[serde(default)]
    pub slip_velocity: Option<f64>,
}

/// Default regularisation velocity of the dynamics' friction law, m/s: a rod that sticks
/// creeps at most this fast (docs/contact.md, "Dynamics").
pub const DEFAULT_SLIP_VELOCITY: f64 = 1e-3;

/// Most obstacles a design may have.
pub const MAX_OBSTACLES: usize = 1000;

fn vector(field: &str, v: Option<[f64; 3]>) -> Result<[f64; 3]> {
    let v = v.ok_or_else(|| SoftrodError::invalid(field, "missing", "is required"))?;
    for (i, x) in v.iter().enumerate() {
        if !x.is_finite() {
            return Err(SoftrodError::invalid(
                format!("{field}[{i}]"),
                x,
                "must be a finite number",
            ));
        }
    }
    Ok(v)
}

fn direction(field: &str, v: Option<[f64; 3]>) -> Result<[f64; 3]> {
    let v = vector(field, v)?;
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if !(n > 0.0 && n.is_finite()) {
        return Err(SoftrodError::invalid(
            field,
            format!("{v:?}"),
            "must be a non-zero direction",
        ));
    }
    Ok(v.map(|x| x / n))
}

fn positive(field: &str, x: f64) -> Result<f64> {
    if !x.is_finite() {
        return Err(SoftrodError::invalid(field, x, "must be a finite number"));
    }
    if x <= 0.0 {
        return Err(SoftrodError::invalid(field, x, "must be > 0"));
    }
    Ok(x)
}

impl ObstacleSpec {
    /// The value of the pose or size field `name` (None: absent).
    fn is_set(&self, name: &str) -> bool {
        match name {
            "point" => self.point.is_some(),
            "normal" => self.normal.is_some(),
            "center" => self.center.is_some(),
            "axis" => self.axis.is_some(),
            "start" => self.start.is_some(),
            "end" => self.end.is_some(),
            "vertices" => self.vertices.is_some(),
            "faces" => self.faces.is_some(),
            _ => self.radius.is_some(),
        }
    }

    /// Regularisation velocity of the friction law, m/s.
    pub fn slip_velocity(&self) -> f64 {
        self.slip_velocity.unwrap_or(DEFAULT_SLIP_VELOCITY)
    }

    /// Smoothing length of the ramp, m.
    pub fn smoothing_length(&self) -> f64 {
        self.smoothing.unwrap_or(0.1 * self.tolerance)
    }

    /// Check obstacle `k`: the kind's pose and size fields present, finite, positive where
    /// they are sizes, no field of another kind; positive stiffness and tolerance, a
    /// smoothing length in (0, tolerance], a friction coefficient >= 0.
    pub fn validate(&self, k: usize) -> Result<()> {
        let f = |name: &str| format!("obstacles[{k}].{name}");
        let need = self.kind.fields();
        for name in [
            "point", "normal", "center", "axis", "start", "end", "radius", "vertices", "faces",
        ] {
            if self.is_set(name) && !need.contains(&name) {
                return Err(SoftrodError::invalid(
                    f(name),
                    "set",
                    format!(
                        "a {} obstacle has no {name} (it takes {})",
                        self.kind.name(),
                        need.join(", ")
                    ),
                ));
            }
        }
        match self.kind {
            ObstacleKind::Plane => {
                vector(&f("point"), self.point)?;
                direction(&f("normal"), self.normal)?;
            }
            ObstacleKind::Sphere => {
                vector(&f("center"), self.center)?;
            }
            ObstacleKind::Cylinder => {
                vector(&f("point"), self.point)?;
                direction(&f("axis"), self.axis)?;
            }
            ObstacleKind::Capsule => {
                let a = vector(&f("start"), self.start)?;
                let b = vector(&f("end"), self.end)?;
                if a == b {
                    return Err(SoftrodError::invalid(
                        f("end"),
                        format!("{b:?}"),
                        "must differ from start (a capsule with one point is a sphere)",
                    ));
                }
            }
            ObstacleKind::Mesh => {
                let missing = |name: &str| SoftrodError::invalid(f(name), "missing", "is required");
                let vertices = self
                    .vertices
                    .as_deref()
                    .ok_or_else(|| missing("vertices"))?;
                let faces = self.faces.as_deref().ok_or_else(|| missing("faces"))?;
                crate::mesh::check(&format!("obstacles[{k}]"), vertices, faces)?;
            }
        }
        if need.contains(&"radius") {
            let r = self
                .radius
                .ok_or_else(|| SoftrodError::invalid(f("radius"), "missing", "is required"))?;
            positive(&f("radius"), r)?;
        }
        positive(&f("stiffness"), self.stiffness)?;
        positive(&f("tolerance"), self.tolerance)?;
        if let Some(e) = self.smoothing {
            positive(&f("smoothing"), e)?;
            if e > self.tolerance {
                return Err(SoftrodError::invalid(
                    f("smoothing"),
                    e,
                    format!(
                        "must be at most the tolerance ({} m): the ramp's smoothing alone sinks the rod by eps/2",
                        self.tolerance
                    ),
                ));
            }
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(SoftrodError::invalid(
                f("friction"),
                self.friction,
                "must be a finite number >= 0",
            ));
        }
        if let Some(v) = self.slip_velocity {
            positive(&f("slip_velocity"), v)?;
        }
        Ok(())
    }
}
