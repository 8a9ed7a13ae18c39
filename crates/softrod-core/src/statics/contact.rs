//! Contact in the statics (docs/contact.md): the frictionless rule and what a solution
//! reports about its contacts. The penalty law itself is `crate::contact`; it enters the
//! shooting ODE as a position-dependent line load, so the shooting Jacobian stays exact.

use crate::contact::{node_contact, NodeContact, Obstacle, StickPoint, Surface};
use crate::error::{Result, SoftrodError};
use crate::jet::RodScalar;
use crate::ode::{integrate_with, step_quadrature, Loads, NodeAt, State};
use crate::rod::Rod;
use crate::statics::{Problem, Solution};

/// Refuse an obstacle with a friction coefficient in a static solve that does not carry
/// friction (the frictionless solves, the sensitivities, inverse statics, the
/// linearisation): Coulomb friction makes a static equilibrium depend on the loading path
/// (a stuck contact holds whatever tangential force the history left in it), and only the
/// path solves (`friction::solve` and `friction::solve_held`, also one per row in
/// `crate::batch::solve_friction_batch` and `solve_held_friction_batch`, and a system's
/// `system::solve_system_friction`) follow a frictional load path.
pub fn frictionless(rod: &Rod) -> Result<()> {
    if let Some(k) = rod.spec.obstacles.iter().position(|o| o.friction != 0.0) {
        return Err(SoftrodError::invalid(
            format!("obstacles[{k}].friction"),
            rod.spec.obstacles[k].friction,
            "this static solve is frictionless (with Coulomb friction the equilibrium depends on the loading path, which only solve_statics, solve_statics_batch, solve_system and solve_system_batch follow: docs/contact.md, \"Friction in the statics\"); set friction = 0 here",
        ));
    }
    Ok(())
}

/// The rod with every obstacle's friction set to 0 (None: it has none to remove): the
/// dynamics' static start. In motion friction is regularised (docs/contact.md,
/// "Dynamics"): at rest, with every velocity zero, it carries no force, so the state a
/// run starts from is the frictionless equilibrium, which the frictionless statics
/// solves.
pub(crate) fn without_friction(rod: &Rod) -> Option<Rod> {
    if !rod.spec.obstacles.iter().any(|o| o.friction != 0.0) {
        return None;
    }
    let mut out = rod.clone();
    for o in &mut out.spec.obstacles {
        o.friction = 0.0;
    }
    out.obstacles = rod.obstacles.as_ref().map(|obs| {
        obs.iter()
            .map(|o| crate::contact::Obstacle {
                friction: 0.0,
                ..o.clone()
            })
            .collect()
    });
    Some(out)
}

/// Refuse an obstacle that the unloaded rod (its reference shape, no loads) already sinks
/// into deeper than the obstacle's tolerance. Every static solve follows the loads from the
/// unloaded rod, so such a start has no load path: Newton would report a singular Jacobian
/// or a failed load step instead of the cause (a table through the hanging actuator, a pin
/// inside its body).
pub fn clear_at_rest(rod: &Rod, loads: &Loads) -> Result<()> {
    let Some(obstacles) = rod.obstacles.as_deref() else {
        return Ok(());
    };
    let n = if loads.base_force_unknown(rod) { 6 } else { 3 };
    let unloaded = node_points(&unloaded_problem(rod, loads), &[0.0; 6][..n]);
    // The first obstacle sunk into beyond its tolerance, at its deepest node.
    for (k, o) in obstacles.iter().enumerate() {
        let deepest = unloaded
            .iter()
            .map(|(s, r, rho)| (*s, rho - o.distance(r).0))
            .fold(
                (0.0, f64::NEG_INFINITY),
                |a, b| if b.1 > a.1 { b } else { a },
            );
        let (s, depth) = deepest;
        if depth > o.tolerance {
            return Err(SoftrodError::invalid(
                format!("obstacles[{k}]"),
                format!("{:?}", rod.spec.obstacles[k].kind).to_lowercase(),
                format!(
                    "the unloaded rod (its reference shape) sinks up to {depth:.3e} m into it (at s = {s:.6} m), deeper than its tolerance {:.3e} m: the statics follows the loads from the unloaded rod, which must start clear of every obstacle; move the obstacle or the mounting",
                    o.tolerance
                ),
            ));
        }
    }
    Ok(())
}

/// Contact force on the rod's rounded end (N, world frame), at the tip's centreline r(L):
/// the end is a hemisphere of the tip's surface radius rho (the tube's closure), a point
/// contact with the penalty of its obstacle over the cap's length, k rho ramp(delta). It has
/// the tube's gap at s = L and acts along the normal through r(L) (no moment about it). It
/// carries a contact that ends at the tip, which the line load alone resolves only with
/// steps shorter than its contact length (docs/contact.md).
pub fn end_force<D: RodScalar>(rod: &Rod, r: &[D; 3]) -> [D; 3] {
    let mut f = [D::from(0.0); 3];
    if let (Some(obstacles), Some(sec)) = (&rod.obstacles, rod.sections.last()) {
        let rho = sec.surface_radius(sec.length);
        for o in obstacles.iter() {
            let g = end_force_of(o, r, rho);
            for k in 0..3 {
                f[k] += g[k];
            }
        }
    }
    f
}

fn end_force_of<D: RodScalar>(o: &Obstacle, r: &[D; 3], rho: f64) -> [D; 3] {
    o.line_force(r, rho).map(|x| x * rho)
}

/// A cold start for a rod with obstacles under dead loads: the equilibrium without the
/// obstacles (3 unknowns, cheap), as the 6 unknowns (n(0), m(0)) of the contact problem.
/// Where that shape touches nothing it is the answer (the penalty is exactly zero off
/// contact) and Newton's first test, an f64 pass, accepts it without a Jacobian; where it
/// touches, Newton starts from a shape close to the answer for light contacts. None when the
/// free solve fails (the caller then follows the natural path from the unloaded rod).
pub(crate) fn free_guess(
    rod: &Rod,
    loads: &Loads,
    opts: &super::SolverOptions,
) -> Option<Vec<f64>> {
    if rod.obstacles.is_none() || loads.has_follower(rod) {
        return None;
    }
    let mut free = rod.clone();
    free.obstacles = None;
    let opts = super::SolverOptions {
        on_invalid: crate::validity::Policy::Ignore,
        ..*opts
    };
    let sol = super::solve(&free, loads, None, &opts).ok()?;
    let p = Problem::new(rod, loads, 1.0);
    let (fs, ms) = (p.force_scale(), p.force_scale() * rod.length);
    let mut x: Vec<f64> = sol.base_force.iter().map(|n| n / fs).collect();
    x.extend(sol.base_moment.iter().map(|m| m / ms));
    Some(x)
}

/// The unloaded problem (load factor 0) integrated without the obstacles' line loads: at
/// x = 0 it is the rod's reference shape even where that already sinks into an obstacle
/// (the penalty would otherwise bend the integration away from the obstacle and hide how
/// deep the reference shape lies in it).
pub(crate) fn unloaded_problem<'a>(rod: &'a Rod, loads: &'a Loads) -> Problem<'a> {
    let mut p = Problem::new(rod, loads, 0.0);
    for c in &mut p.coeffs {
        c.obstacles = None;
    }
    p
}

/// A shape's nodes for [`crossing`]: arc length, position and surface radius, base first.
pub(crate) type NodePoints = Vec<(f64, [f64; 3], f64)>;

/// The nodes of the rod at the shooting unknowns `x` of problem `p`.
pub(crate) fn node_points(p: &Problem, x: &[f64]) -> NodePoints {
    let rod = p.rod;
    let mut out = Vec::with_capacity(rod.sections.iter().map(|s| s.steps + 1).sum());
    let mut visit = |i: usize, s: f64, y: &State<f64>| {
        let sec = &rod.sections[i];
        out.push((s, y.r, sec.surface_radius(s - sec.s_start)));
    };
    crate::ode::integrate(rod, &p.coeffs, p.base_state(x), Some(&mut visit));
    out
}

/// The first node whose straight path from shape `a` to shape `b` (the same nodes, from
/// [`node_points`]) passes through an obstacle: goes deeper into it than its tolerance
/// beyond the deeper of its two ends (the load path's intermediate levels are solved to a
/// loose tolerance and may sink a little deeper than the answer; a crossing goes through):
/// (obstacle, s, depth), or None. A static solve is an equilibrium, not a motion, and a pin
/// or ball the rod hangs on has equilibria on both sides of it: the one the rod reaches
/// from its unloaded shape does not cross it. To a plane a straight path cannot cross
/// without ending inside it (the gap is linear along it); to a sphere, cylinder or capsule
/// it can.
pub(crate) fn crossing(
    obstacles: &[Obstacle],
    a: &[(f64, [f64; 3], f64)],
    b: &[(f64, [f64; 3], f64)],
) -> Option<(usize, f64, f64)> {
    if a.len() != b.len() {
        return None;
    }
    a.iter()
        .zip(b)
        .find_map(|((s, ra, rho_a), (_, rb, rho_b))| {
            let path = crate::contact::Piece {
                c: [
                    *ra,
                    std::array::from_fn(|i| rb[i] - ra[i]),
                    [0.0; 3],
                    [0.0; 3],
                ],
                s: *s,
                h: 0.0,
                rho: [*rho_a, *rho_b],
            };
            let ends = |k: usize| {
                let o = &obstacles[k];
                let depth = |r: &[f64; 3], rho: f64| rho - o.distance(r).0;
                o.tolerance + depth(ra, *rho_a).max(depth(rb, *rho_b)).max(0.0)
            };
            crate::contact::deepest_beyond(obstacles, &path, ends)
                .map(|(k, _, depth)| (k, *s, depth))
        })
}

/// Whether no node of shape `a` is deeper in an obstacle than its tolerance (a shape from
/// which paths can be followed; an unloaded rod placed into an obstacle has no side).
pub(crate) fn clear(obstacles: &[Obstacle], a: &[(f64, [f64; 3], f64)]) -> bool {
    a.iter().all(|(_, r, rho)| {
        obstacles
            .iter()
            .all(|o| rho - o.distance(r).0 <= o.tolerance)
    })
}

/// The nodes of the rod of problem `p` at the unknowns `x` of the shape a solve starts from
/// (its unloaded rod), from which its answer must be reachable without a node's path
/// crossing an obstacle ([`crossing`]); None where nothing is to be checked: no obstacle
/// a straight path can cross without ending inside it (planes only: the gap is linear along
/// the path, so tables and walls cost no extra pass), or a start already inside one.
pub(crate) fn start_nodes(p: &Problem, x: &[f64]) -> Option<NodePoints> {
    let obstacles = p.rod.obstacles.as_deref().filter(|o| crossable(o))?;
    let shape = node_points(p, x);
    clear(obstacles, &shape).then_some(shape)
}

/// Whether a straight node path could pass through one of `obstacles` and end outside it:
/// not through a plane.
pub(crate) fn crossable(obstacles: &[Obstacle]) -> bool {
    obstacles
        .iter()
        .any(|o| !matches!(o.surface, Surface::Plane { .. }))
}

/// A node path that passes through an obstacle ([`crossing`]): the rod (its index in a
/// system; None for a lone rod), the obstacle, the node's arc length s (m) and how deep the
/// path goes (m).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Crossing {
    pub rod: Option<usize>,
    pub obstacle: usize,
    pub s: f64,
    pub depth: f64,
}

impl Crossing {
    /// A lone rod's crossing, from [`crossing`]'s (obstacle, s, depth).
    pub(crate) fn lone((obstacle, s, depth): (usize, f64, f64)) -> Self {
        Crossing {
            rod: None,
            obstacle,
            s,
            depth,
        }
    }
}

/// The rods of a held-tip or system solve at one shape, for the crossing check: per rod,
/// its nodes (None where its crossings are not checked, [`start_nodes`]).
pub(crate) struct Sides(Vec<Option<NodePoints>>);

impl Sides {
    /// At the shape a path starts from: each rod's problem and unknowns.
    pub(crate) fn start(rods: &[(&Problem, &[f64])]) -> Self {
        Sides(rods.iter().map(|(p, x)| start_nodes(p, x)).collect())
    }

    /// Whether no rod's crossings are checked (nothing to compute along the path).
    pub(crate) fn unchecked(&self) -> bool {
        self.0.iter().all(Option::is_none)
    }

    /// The same rods at another shape (the rods checked at the start only).
    pub(crate) fn at(&self, rods: &[(&Problem, &[f64])]) -> Self {
        Sides(
            self.0
                .iter()
                .zip(rods)
                .map(|(a, (p, x))| a.as_ref().map(|_| node_points(p, x)))
                .collect(),
        )
    }

    /// The first node path from `self` to `to` that passes through an obstacle; `rods`
    /// gives the obstacles, and `system` whether the rods are a system's (named by index).
    pub(crate) fn crossing(
        &self,
        to: &Sides,
        rods: &[(&Problem, &[f64])],
        system: bool,
    ) -> Option<Crossing> {
        self.0
            .iter()
            .zip(&to.0)
            .zip(rods)
            .enumerate()
            .find_map(|(i, ((a, b), (p, _)))| {
                let (a, b, obstacles) = (a.as_ref()?, b.as_ref()?, p.rod.obstacles.as_deref()?);
                crossing(obstacles, a, b).map(|(obstacle, s, depth)| Crossing {
                    rod: system.then_some(i),
                    obstacle,
                    s,
                    depth,
                })
            })
    }
}

/// The error for a solve whose rod passes through an obstacle (`c`) on the way from its
/// unloaded shape: in load steps down to `step`, or (None) to the equilibrium Newton found
/// from the start it was given, without continuation.
pub(crate) fn crossing_error(c: Crossing, step: Option<f64>) -> SoftrodError {
    let (k, s, depth) = (c.obstacle, c.s, c.depth);
    let name = match c.rod {
        Some(i) => format!("rods[{i}].obstacles[{k}]"),
        None => format!("obstacles[{k}]"),
    };
    let reason = match step {
        Some(step) => format!(
            "no equilibrium reached from the unloaded rod without passing through {name}: the node at s = {s:.6} m goes {depth:.3e} m into it between load levels even in load steps of {step:.3e} (the load pushes the rod through the penalty: raise the obstacle's stiffness, or its tolerance)"
        ),
        None => format!(
            "the equilibrium found from the given start lies beyond {name}: the node at s = {s:.6} m would pass {depth:.3e} m into it on the way from the unloaded rod; turn continuation on to follow the load from the unloaded rod"
        ),
    };
    SoftrodError::NotConverged {
        iterations: 0,
        residual: f64::NAN,
        load_factor: 0.0,
        reason,
    }
}

/// The contacts of a static solution.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactReport {
    /// One entry per node of the solution's shape (base, then every step's end): nearest
    /// obstacle, gap, nearest obstacle point, contact force per unit length.
    pub nodes: Vec<NodeContact>,
    /// Resultant contact force of each obstacle on the rod, N (world frame): the integral
    /// of its line force with the integrator's own quadrature (RK4 stages), i.e. exactly
    /// the force the solve applied.
    pub force: Vec<[f64; 3]>,
    /// Moment of each obstacle's contact forces about the base position, N m.
    pub moment: Vec<[f64; 3]>,
    /// The part of `force` on the rod's rounded end (`end_force`), per obstacle, N.
    pub end: Vec<[f64; 3]>,
    /// The tangential (friction) part of `force`, per obstacle, N (zero without friction;
    /// the frictional statics, `crate::statics::friction`).
    pub friction: Vec<[f64; 3]>,
    /// Deepest penetration of the rod's surface into any obstacle at a node, m (<= 0: no
    /// node touches).
    pub max_penetration: f64,
}

/// The contact report of a converged shooting solution `sol` of `loads`; None for a rod
/// without obstacles. The loads are checked against the rod (they must be those `sol` was
/// solved with) and `sol`'s unknowns must be a shooting solution's (3 or 6).
pub fn report(rod: &Rod, loads: &Loads, sol: &Solution) -> Result<Option<ContactReport>> {
    let Some(obstacles) = rod.obstacles.as_ref() else {
        return Ok(None);
    };
    rod.check_loads(&loads.pressures, &loads.stiffness_scale)?;
    rod.check_tensions(&loads.tensions)?;
    if !matches!(sol.x.len(), 3 | 6) {
        return Err(SoftrodError::invalid(
            "solution.x",
            format!("{} numbers", sol.x.len()),
            "must be a shooting solution's unknowns (3, or 6 with obstacles or follower loads)",
        ));
    }
    let p = Problem::for_solution(rod, loads, sol);
    let points = sol.friction.as_ref().map(|f| &f.state);
    let y0: State<f64> = p.base_state(&sol.x);
    let base = rod.base_position;
    let mut nodes = Vec::new();
    let n_obs = obstacles.len();
    let mut force = vec![[0.0; 3]; n_obs];
    let mut moment = vec![[0.0; 3]; n_obs];
    let mut friction = vec![[0.0; 3]; n_obs];
    // Obstacle k's load on a point at state y (surface radius rho, `scale` 1 for the line
    // load, rho for the rounded end): force, moment about the centreline, friction part.
    let load = |k: usize, y: &State<f64>, rho: f64, scale: f64, old: Option<&StickPoint>| {
        let o = &obstacles[k];
        match old {
            Some(old) => {
                let g = o.stick_load(&y.r, &y.rot, rho, scale, old, k);
                (g.force, g.moment, g.friction)
            }
            None => (
                o.line_force(&y.r, rho).map(|f| f * scale),
                [0.0; 3],
                [0.0; 3],
            ),
        }
    };
    let mut add = |k: usize, w: f64, at: &[f64; 3], (f, m, t): ([f64; 3], [f64; 3], [f64; 3])| {
        let arm: [f64; 3] = std::array::from_fn(|i| at[i] - base[i]);
        let mo = [
            arm[1] * f[2] - arm[2] * f[1],
            arm[2] * f[0] - arm[0] * f[2],
            arm[0] * f[1] - arm[1] * f[0],
        ];
        for i in 0..3 {
            force[k][i] += w * f[i];
            moment[k][i] += w * (mo[i] + m[i]);
            friction[k][i] += w * t[i];
        }
    };
    let mut hook = |node: NodeAt, y: &mut State<f64>| {
        let sec = &rod.sections[node.section];
        let stage_points = points.map(|st| &st.sections[node.section]);
        if node.step > 0 || node.section == 0 {
            let rho = sec.surface_radius(node.s - sec.s_start);
            if let Some(mut nc) = node_contact(obstacles, &y.r, rho) {
                // With friction: the load of the stage point at the node (the step's
                // first, or the section's last step's last).
                let stage = if node.step < sec.steps {
                    4 * node.step
                } else {
                    (4 * node.step).saturating_sub(1)
                };
                if let Some(old) = stage_points.and_then(|pts| pts.get(stage)) {
                    nc.force = [0.0; 3];
                    for k in 0..n_obs {
                        let (f, _, _) = load(k, y, rho, 1.0, Some(old));
                        for i in 0..3 {
                            nc.force[i] += f[i];
                        }
                    }
                }
                nodes.push(nc);
            }
        }
        let mut j = 4 * node.step;
        step_quadrature(rod, &p.coeffs, node, y, &mut |ys, s, w| {
            let rho = sec.surface_radius(s);
            let old = stage_points.and_then(|pts| pts.get(j));
            j += 1;
            for k in 0..n_obs {
                add(k, w, &ys.r, load(k, ys, rho, 1.0, old));
            }
        });
        false
    };
    let tip = integrate_with(rod, &p.coeffs, y0, &mut hook);
    let mut end = vec![[0.0; 3]; n_obs];
    if let Some(sec) = rod.sections.last() {
        let rho = sec.surface_radius(sec.length);
        for (k, e) in end.iter_mut().enumerate() {
            let l = load(k, &tip, rho, rho, points.map(|st| &st.end));
            *e = l.0;
            add(k, 1.0, &tip.r, l);
        }
    }
    let max_penetration = nodes
        .iter()
        .map(|n| -n.gap)
        .fold(f64::NEG_INFINITY, f64::max);
    Ok(Some(ContactReport {
        nodes,
        force,
        moment,
        end,
        friction,
        max_penetration,
    }))
}
