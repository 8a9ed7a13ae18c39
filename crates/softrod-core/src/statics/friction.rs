//! Coulomb friction in the statics (docs/contact.md, "Friction in the statics"): a
//! quasi-static load path with elastic-slip (penalty) friction and a return map.
//!
//! With friction an equilibrium depends on how the loads got there: a stuck contact keeps
//! whatever tangential force its history left in it. So the solve follows a load path in
//! equal increments, from the unloaded rod (no tangential load stored anywhere) or from
//! a previous frictional solution (`FrictionPath`: its loads and contact memory), to the
//! requested loads. Every contact point (each RK4 stage point of the shooting integration,
//! and the rounded end) keeps, from the last converged increment, its section's position
//! and rotation and the elastic tangential displacement e of each obstacle's tangential
//! penalty spring. Within an increment's Newton solve the friction is the return map of
//! the trial state (`crate::contact::Obstacle::stick_load`); after convergence the state
//! is updated. This is the standard incremental treatment of Wriggers, "Computational
//! Contact Mechanics", Springer 2006, DOI 10.1007/978-3-540-32609-0 (ch. 5, friction and
//! its return mapping), with the tangential stiffness equal to the normal penalty's.
//!
//! A held (pinned or clamped) tip (`solve_held`) follows the same path with its
//! prescribed pose moved along it in the same increments, from the unloaded rod's tip
//! (or the history's held pose) to the requested one, each increment the constrained
//! Newton solve (`constraint::Held`); one increment loop (`follow`), generic over the
//! inner solve, serves both.
//!
//! Within an increment the slip is measured from the increment's start: a point that
//! comes into contact during an increment is anchored where its material point was at the
//! start, and a stick/slip change is resolved at the increment's end. The answer is
//! therefore first order in the increment size (docs/contact.md). Friction has no
//! potential, so stability is not assessed (`stable` is None).

use std::sync::Arc;

use super::constraint::{
    self, conclude_at, ConstrainedSolution, Held, NewtonOk, PathOk, Pose, IDENTITY,
};
use super::{
    check_inputs_any_friction, contact, At, Attempt, Converged, Problem, Shape, Solution,
    SolverOptions, Start, MIN_CROSSING_STEP,
};
use crate::contact::{Obstacle, StickPoint};
use crate::error::{Result, SoftrodError};
use crate::jet::RodScalar;
use crate::ode::{integrate_with, step_quadrature, Loads, NodeAt, State};
use crate::rod::Rod;
use constraint::TipConstraint;

/// Default number of equal load increments of a frictional static solve. The answer's
/// dependence on the increment size is first order (measured on the bundled finger
/// pressed onto a table with mu = 0.5 at 35 kPa: the friction force changes by 0.37 and
/// 0.084 mN from 80 to 320 and 1280 increments, a ratio of 4.3 per quadrupling); 80
/// increments leave about 1 % of the friction force (0.5 of 45 mN). Coarser requests land
/// on an obstacle in increments of the default's length (`LANDING_STEP`).
pub const DEFAULT_FRICTION_STEPS: usize = 80;
/// Most increments a caller may ask for (each is a Newton solve).
pub const MAX_FRICTION_STEPS: usize = 100_000;
/// A failed increment is halved down to 1/SUB of the requested one, or of the default
/// path's increment (1/DEFAULT_FRICTION_STEPS of the path) where the request is coarser
/// (`sub_increments`).
const SUB: u64 = 1024;
/// Contact-free stretches of a path are jumped over (`follow`).
pub(crate) const JUMPS: bool = true;
/// The longest increment (fraction of the path) in which a contact point may land on an
/// obstacle: the default path's (`follow`), with a margin for the round-off of the
/// dyadic positions.
const LANDING_STEP: f64 = (1.0 + 1e-9) / DEFAULT_FRICTION_STEPS as f64;

/// Every contact point's friction memory: per section, one point per RK4 stage (4 per
/// step; none in a rigid section, which carries no contact force), and the rounded end.
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionState {
    pub sections: Vec<Arc<[StickPoint]>>,
    pub end: StickPoint,
}

/// Where a frictional path stands at a converged equilibrium: the loads reached, the
/// friction state and the shooting unknowns there, how the tip was held (and where), and
/// the design it belongs to. A further path (unloading, say) starts from it.
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionPath {
    pub loads: Loads,
    pub state: FrictionState,
    pub x: Vec<f64>,
    /// The tip's end condition at the path's end: free, or held at the pose reached.
    pub held: TipConstraint,
    spec: crate::spec::DesignSpec,
}

impl FrictionPath {
    /// Largest |e| over all contact points and obstacles (m): the elastic tangential
    /// displacement stored in the contacts (0: no tangential load held).
    pub fn max_elastic_slip(&self) -> f64 {
        self.state.max_elastic_slip()
    }

    /// The path of a rod whose tip a system's platform held at `tip` (a clamp there): its
    /// loads, state and unknowns, so that it can go on as a lone clamped rod.
    pub(crate) fn clamped_at(
        rod: &Rod,
        loads: &Loads,
        state: FrictionState,
        x: &[f64],
        tip: &State<f64>,
    ) -> Self {
        FrictionPath {
            loads: loads.clone(),
            state,
            x: x.to_vec(),
            held: TipConstraint::Clamped {
                position: tip.r,
                rotation: tip.rot,
            },
            spec: rod.spec.clone(),
        }
    }
}

impl FrictionState {
    /// Largest |e| over all contact points and obstacles (m).
    pub fn max_elastic_slip(&self) -> f64 {
        self.sections
            .iter()
            .flat_map(|s| s.iter())
            .chain(std::iter::once(&self.end))
            .flat_map(|p| p.e.iter())
            .map(|e| (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
            .fold(0.0, f64::max)
    }
}

/// Whether some obstacle of the rod has friction > 0 (the static solve then follows the
/// frictional path).
pub fn has_friction(rod: &Rod) -> bool {
    rod.spec.obstacles.iter().any(|o| o.friction != 0.0)
}

/// Refuse a `history` (a friction state to continue a path from) on a rod without
/// friction, whose equilibrium does not depend on the load path.
pub fn check_history_wanted(rod: &Rod, history_given: bool) -> Result<()> {
    if history_given && !has_friction(rod) {
        return Err(SoftrodError::invalid(
            "history",
            "a friction state",
            "this design has no obstacle with friction > 0: a frictionless equilibrium does not depend on the load path",
        ));
    }
    Ok(())
}

/// The rounded end's contact load with friction (`crate::statics::contact::end_force`
/// plus its tangential part): the total force and the friction's moment about the tip's
/// centreline.
pub(crate) fn end_load<D: RodScalar>(
    rod: &Rod,
    r: &[D; 3],
    rot: &[[D; 3]; 3],
    old: &StickPoint,
) -> ([D; 3], [D; 3]) {
    let mut f = [D::from(0.0); 3];
    let mut m = [D::from(0.0); 3];
    if let (Some(obstacles), Some(sec)) = (&rod.obstacles, rod.sections.last()) {
        let rho = sec.surface_radius(sec.length);
        let g = crate::contact::total_stick_load(obstacles, r, rot, rho, rho, old);
        f = g.force;
        m = g.moment;
    }
    (f, m)
}

/// A point with no stored tangential displacement at state y.
fn fresh(y: &State<f64>, n_obstacles: usize) -> StickPoint {
    StickPoint {
        r: y.r,
        rot: y.rot,
        e: vec![[0.0; 3]; n_obstacles],
    }
}

/// The friction state of the unloaded rod (its reference shape; x = 0 at zero load):
/// every point where the rod is, nothing stored; and its tip (where a held tip's path
/// starts).
pub(crate) fn unloaded_state(
    rod: &Rod,
    loads: &Loads,
    obstacles: &[Obstacle],
) -> (FrictionState, State<f64>) {
    // The reference shape, without the obstacles: a bed the rod touches within its
    // tolerance already pushes on it at zero load, and x = 0 is then not its equilibrium.
    let mut free = rod.clone();
    free.obstacles = None;
    let rod = &free;
    let p = Problem::new(rod, loads, 0.0);
    let k = obstacles.len();
    let mut sections: Vec<Vec<StickPoint>> = vec![Vec::new(); rod.sections.len()];
    let mut hook = |node: NodeAt, y: &mut State<f64>| {
        step_quadrature(rod, &p.coeffs, node, y, &mut |ys, _, _| {
            sections[node.section].push(fresh(ys, k));
        });
        false
    };
    let tip = integrate_with(rod, &p.coeffs, p.base_state(&[0.0; 6]), &mut hook);
    let state = FrictionState {
        sections: sections.into_iter().map(Arc::from).collect(),
        end: fresh(&tip, k),
    };
    (state, tip)
}

/// The state after a converged increment: problem `p` (built on `old`) at its solution
/// x, each point's return map (`Obstacle::stick_load`) at its new position; and whether a
/// point landed on an obstacle in the increment (clear of it at the start, penetrating it
/// now).
fn advance(
    p: &Problem,
    x: &[f64],
    old: &FrictionState,
    obstacles: &[Obstacle],
) -> (FrictionState, bool) {
    let rod = p.rod;
    let mut sections: Vec<Vec<StickPoint>> = vec![Vec::new(); rod.sections.len()];
    let landed = std::cell::Cell::new(false);
    let update = |ys: &State<f64>, rho: f64, scale: f64, was: &StickPoint| StickPoint {
        r: ys.r,
        rot: ys.rot,
        e: (0..obstacles.len())
            .map(|k| {
                let o = &obstacles[k];
                if rho > o.distance(&ys.r).0 && rho < o.distance(&was.r).0 {
                    landed.set(true);
                }
                o.stick_load(&ys.r, &ys.rot, rho, scale, was, k).e
            })
            .collect(),
    };
    let mut hook = |node: NodeAt, y: &mut State<f64>| {
        let sec = &rod.sections[node.section];
        let points = &old.sections[node.section];
        let mut j = 4 * node.step;
        step_quadrature(rod, &p.coeffs, node, y, &mut |ys, s, _| {
            if let Some(was) = points.get(j) {
                sections[node.section].push(update(ys, sec.surface_radius(s), 1.0, was));
            }
            j += 1;
        });
        false
    };
    let tip = integrate_with(rod, &p.coeffs, p.base_state(x), &mut hook);
    let end = match rod.sections.last() {
        Some(sec) => {
            let rho = sec.surface_radius(sec.length);
            update(&tip, rho, rho, &old.end)
        }
        None => old.end.clone(),
    };
    let state = FrictionState {
        sections: sections.into_iter().map(Arc::from).collect(),
        end,
    };
    (state, landed.get())
}

/// Check that `history` belongs to this rod (same design, same obstacles) and to a path
/// with the same end condition (`held`: free, pinned or clamped), and that its loads can
/// be joined to `loads` by a straight path.
fn check_history(
    rod: &Rod,
    loads: &Loads,
    held: &TipConstraint,
    history: &FrictionPath,
) -> Result<()> {
    check_design("history", &history.spec, rod)?;
    if history.held.name() != held.name() {
        return Err(SoftrodError::invalid(
            "history",
            format!("a frictional solution with a {} tip", history.held.name()),
            format!(
                "this solve's tip is {}: a friction path continues with the end condition it was solved with (the contacts' memory belongs to that path; a held tip's pose moves along the path, a free tip's loads do)",
                held.name()
            ),
        ));
    }
    check_joinable("history", &history.loads, loads)
}

/// Check that a friction state solved with design `spec` (in the `field` named) belongs
/// to `rod`: the same design, the same obstacles.
pub(crate) fn check_design(field: &str, spec: &crate::spec::DesignSpec, rod: &Rod) -> Result<()> {
    if spec.obstacles != rod.spec.obstacles {
        return Err(SoftrodError::invalid(
            field,
            "a frictional solution",
            "its obstacles differ from this design's: a friction state belongs to the design and obstacles it was solved with",
        ));
    }
    if *spec != rod.spec {
        return Err(SoftrodError::invalid(
            field,
            format!("a frictional solution of design {:?}", spec.name),
            format!(
                "it belongs to another design than {:?} (a friction state belongs to the design it was solved with)",
                rod.spec.name
            ),
        ));
    }
    Ok(())
}

/// Check that a path can go from the loads `h` of a previous frictional solution (in the
/// `field` named) to `loads` along a straight line: the same tip frame, stiffness scale
/// and numbers of channels.
pub(crate) fn check_joinable(field: &str, h: &Loads, loads: &Loads) -> Result<()> {
    if h.tip_frame != loads.tip_frame {
        return Err(SoftrodError::invalid(
            field,
            format!("tip frame {:?}", h.tip_frame),
            "its tip loads act in another frame than this solve's",
        ));
    }
    if h.stiffness_scale != loads.stiffness_scale {
        return Err(SoftrodError::invalid(
            field,
            format!("stiffness scale {:?}", h.stiffness_scale),
            format!(
                "differs from this solve's {:?}: the path changes the loads, not the material",
                loads.stiffness_scale
            ),
        ));
    }
    if h.pressures.len() != loads.pressures.len() || h.tensions.len() != loads.tensions.len() {
        return Err(SoftrodError::invalid(
            field,
            "a frictional solution",
            "its pressures or tensions have another number of channels than this solve's",
        ));
    }
    Ok(())
}

/// The loads at path parameter t in [0, 1] from `a` to `b` (straight), with the load
/// factor of the problem: from the unloaded rod (`a` None) the loads `b` scaled by t, else
/// `a + t (b - a)` at full factor (gravity and the tip body's weight are on already).
fn loads_at(a: Option<&Loads>, b: &Loads, t: f64) -> (Loads, f64) {
    match a {
        None => (b.clone(), t),
        Some(a) => {
            let mix = |x: f64, y: f64| if t >= 1.0 { y } else { x + t * (y - x) };
            let lerp = |x: &[f64], y: &[f64]| -> Vec<f64> {
                x.iter().zip(y).map(|(x, y)| mix(*x, *y)).collect()
            };
            let lerp3 = |x: &[f64; 3], y: &[f64; 3]| -> [f64; 3] {
                std::array::from_fn(|i| mix(x[i], y[i]))
            };
            (
                Loads {
                    pressures: lerp(&a.pressures, &b.pressures),
                    tensions: lerp(&a.tensions, &b.tensions),
                    tip_force: lerp3(&a.tip_force, &b.tip_force),
                    tip_moment: lerp3(&a.tip_moment, &b.tip_moment),
                    tip_frame: b.tip_frame,
                    stiffness_scale: b.stiffness_scale,
                },
                1.0,
            )
        }
    }
}

/// Check the number of increments of a frictional solve.
pub fn check_steps(steps: usize) -> Result<()> {
    if steps == 0 || steps > MAX_FRICTION_STEPS {
        return Err(SoftrodError::invalid(
            "friction_steps",
            steps,
            format!("must be in 1..={MAX_FRICTION_STEPS}"),
        ));
    }
    Ok(())
}

/// The frictional static solve of a free tip: from `history` (a previous frictional
/// solution of this rod; None: the unloaded rod) to `loads` in `steps` equal increments
/// of the path, each halved while its Newton solve fails (down to 1/1024 of it, or of the
/// default path's increment where `steps` is smaller than the default: `sub_increments`). The
/// solution carries its `FrictionPath`; `stable` is None. Errors name what is wrong:
/// `friction_steps`, `history`, an obstacle crossed, or the increment that failed.
pub fn solve(
    rod: &Rod,
    loads: &Loads,
    history: Option<&FrictionPath>,
    steps: usize,
    opts: &SolverOptions,
) -> Result<Solution> {
    solve_inner(rod, loads, history, steps, opts, false, JUMPS).map(|(s, _)| s)
}

/// [`solve`] and the shape at every integration node.
pub fn solve_with_shape(
    rod: &Rod,
    loads: &Loads,
    history: Option<&FrictionPath>,
    steps: usize,
    opts: &SolverOptions,
) -> Result<(Solution, Shape)> {
    solve_inner(rod, loads, history, steps, opts, true, JUMPS)
        .map(|(s, sh)| (s, sh.unwrap_or_default()))
}

/// [`solve`] without jumping over the path's contact-free stretches (every requested
/// increment solved): for tests that the jumps leave the answer as it was.
#[doc(hidden)]
pub fn solve_every_increment(
    rod: &Rod,
    loads: &Loads,
    history: Option<&FrictionPath>,
    steps: usize,
    opts: &SolverOptions,
) -> Result<Solution> {
    solve_inner(rod, loads, history, steps, opts, false, false).map(|(s, _)| s)
}

fn solve_inner(
    rod: &Rod,
    loads: &Loads,
    history: Option<&FrictionPath>,
    steps: usize,
    opts: &SolverOptions,
    want_shape: bool,
    jumps: bool,
) -> Attempt {
    let free = TipConstraint::Free;
    let mut b = begin(rod, loads, &free, history, steps, opts)?;
    let violations = std::mem::take(&mut b.violations);
    let end = b.follow(rod, loads, history, steps, jumps, |p, _, guess| {
        p[0].newton(std::array::from_fn(|i| guess[i]), Start::Guess, opts)
    })?;
    let p = end.problem(0, rod, loads);
    let (mut sol, shape) = p.conclude(
        At::Converged(&end.last),
        end.iterations,
        end.levels,
        opts,
        violations,
        want_shape,
    )?;
    sol.friction = Some(end.path(rod, loads, free));
    Ok((sol, shape))
}

/// The frictional static solve of a tip held by `constraint` (pinned or clamped,
/// `super::constraint`): the path of [`solve`], along which the held pose moves too, from
/// where the path starts (the unloaded rod's tip, or `history`'s held pose) to the
/// prescribed one in the same increments (the position on a straight line, the rotation
/// on the geodesic). Each increment is the constrained Newton solve
/// (`constraint::Held`). The solution carries its `FrictionPath` and the tip reaction
/// (as `constraint::solve_constrained` reports it); `stable` is None.
pub fn solve_held(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    history: Option<&FrictionPath>,
    steps: usize,
    opts: &SolverOptions,
) -> Result<ConstrainedSolution> {
    constraint.validate()?;
    if matches!(constraint, TipConstraint::Free) {
        return Err(SoftrodError::invalid(
            "constraint",
            "free",
            "must be pinned or clamped (a free tip: friction::solve)",
        ));
    }
    let mut b = begin(rod, loads, constraint, history, steps, opts)?;
    let mut violations = std::mem::take(&mut b.violations);
    let (r0, rot0) = b.pose;
    // One kept matrix along the path: consecutive increments are nearby problems.
    let mut chord = constraint::Chord::default();
    let end = b.follow(rod, loads, history, steps, JUMPS, |p, t, guess| {
        let eq = Held {
            p: &p[0],
            pose: Pose::along(constraint, &r0, &rot0, t),
        };
        chord.solve(&eq, guess, opts.tol, opts.max_iter)
    })?;
    let p = end.problem(0, rod, loads);
    let done = PathOk {
        x: end.x.clone(),
        residual: end.last.residual,
        iterations: end.iterations,
        load_steps: end.levels,
    };
    let mut out = conclude_at(&p, constraint, done, opts, &mut violations)?;
    out.solution.friction = Some(end.path(rod, loads, *constraint));
    Ok(out)
}

/// Where a lone rod's frictional path starts, its inputs checked.
struct Begin {
    violations: Vec<SoftrodError>,
    state: FrictionState,
    x: [f64; 6],
    /// The held tip's pose there (the unloaded rod's tip, or `history`'s held pose).
    pose: ([f64; 3], [[f64; 3]; 3]),
}

impl Begin {
    /// The lone rod's path from here to `loads` (`follow`).
    fn follow<C: Reached>(
        self,
        rod: &Rod,
        loads: &Loads,
        history: Option<&FrictionPath>,
        steps: usize,
        jumps: bool,
        inner: impl FnMut(&mut Vec<Problem>, f64, Vec<f64>) -> std::result::Result<C, (usize, f64)>,
    ) -> Result<PathEnd<C>> {
        let leg = Leg {
            rod,
            loads,
            start: history.map(|h| &h.loads),
        };
        follow(
            &[leg],
            vec![Some(self.state)],
            self.x.to_vec(),
            steps,
            false,
            jumps,
            inner,
        )
    }
}

/// Check the inputs of a frictional solve whose tip is `held` (free, pinned or clamped)
/// and find where its path starts.
fn begin(
    rod: &Rod,
    loads: &Loads,
    held: &TipConstraint,
    history: Option<&FrictionPath>,
    steps: usize,
    opts: &SolverOptions,
) -> Result<Begin> {
    check_steps(steps)?;
    let violations = check_inputs_any_friction(rod, loads, opts)?;
    let Some(obstacles) = rod.obstacles.as_deref() else {
        return Err(SoftrodError::invalid(
            "obstacles",
            "none",
            "the frictional static solve needs obstacles (a design without any is frictionless)",
        ));
    };
    let Some(h) = history else {
        let (state, tip) = unloaded_state(rod, loads, obstacles);
        return Ok(Begin {
            violations,
            state,
            x: [0.0; 6],
            pose: (tip.r, tip.rot),
        });
    };
    check_history(rod, loads, held, h)?;
    if h.x.len() != 6 {
        return Err(SoftrodError::invalid(
            "history",
            "a frictional solution",
            "its shooting unknowns are not the six of a path with obstacles",
        ));
    }
    let pose = match h.held {
        TipConstraint::Free => ([0.0; 3], IDENTITY),
        // A pin prescribes no rotation (`Pose` does not read it).
        TipConstraint::Pinned { position } => (position, IDENTITY),
        TipConstraint::Clamped { position, rotation } => (position, rotation),
    };
    Ok(Begin {
        violations,
        state: h.state.clone(),
        x: std::array::from_fn(|i| h.x[i]),
        pose,
    })
}

/// What an increment's inner Newton solve reached.
pub(crate) trait Reached {
    fn x(&self) -> Vec<f64>;
    fn iterations(&self) -> usize;
}

impl Reached for Converged<6> {
    fn x(&self) -> Vec<f64> {
        self.x.to_vec()
    }
    fn iterations(&self) -> usize {
        self.iterations
    }
}

impl Reached for NewtonOk {
    fn x(&self) -> Vec<f64> {
        self.x.clone()
    }
    fn iterations(&self) -> usize {
        self.iterations
    }
}

/// One rod on a frictional path: its design, the loads the path goes to, and the loads it
/// starts from (None: the unloaded rod, whose gravity comes on with the loads).
pub(crate) struct Leg<'r> {
    pub rod: &'r Rod,
    pub loads: &'r Loads,
    pub start: Option<&'r Loads>,
}

impl Leg<'_> {
    /// Its problem at path parameter t with the friction state `state` of the last
    /// converged increment (None: a rod without obstacles, which carries none).
    fn problem<'p>(&'p self, at: &'p (Loads, f64), state: Option<&FrictionState>) -> Problem<'p> {
        match state {
            Some(s) => Problem::with_friction(self.rod, &at.0, at.1, s),
            None => Problem::new(self.rod, &at.0, at.1),
        }
    }
}

/// The end of a frictional path: the last increment's solve (at the full loads), each
/// rod's friction state it was solved with and the one advanced at its solution, the
/// unknowns (6 per rod, then whatever else the inner solve carries) and the effort.
pub(crate) struct PathEnd<C> {
    pub last: C,
    pub states: Vec<Option<FrictionState>>,
    pub next: Vec<Option<FrictionState>>,
    pub x: Vec<f64>,
    pub iterations: usize,
    pub levels: usize,
}

impl<C> PathEnd<C> {
    /// Where a lone rod's path stands at its end, for a further path to start from.
    fn path(mut self, rod: &Rod, loads: &Loads, held: TipConstraint) -> Arc<FrictionPath> {
        Arc::new(FrictionPath {
            loads: loads.clone(),
            state: self
                .next
                .swap_remove(0)
                .expect("a frictional rod has a friction state"),
            x: self.x[..6].to_vec(),
            held,
            spec: rod.spec.clone(),
        })
    }

    /// Rod i's solve problem at the path's end (its friction state of the last increment).
    pub(crate) fn problem<'a>(&self, i: usize, rod: &'a Rod, loads: &'a Loads) -> Problem<'a> {
        match &self.states[i] {
            Some(s) => Problem::with_friction(rod, loads, 1.0, s),
            None => Problem::new(rod, loads, 1.0),
        }
    }
}

/// The legs' problems at one path level (`levels`: each leg's loads and load factor) with
/// the friction states of the last converged increment.
fn problems_at<'p>(
    legs: &'p [Leg],
    levels: &'p [(Loads, f64)],
    states: &[Option<FrictionState>],
) -> Vec<Problem<'p>> {
    legs.iter()
        .zip(levels)
        .zip(states)
        .map(|((leg, at), s)| leg.problem(at, s.as_ref()))
        .collect()
}

/// Each rod's problem with its six unknowns (the first 6 per rod of `x`).
fn rods_of<'p>(problems: &'p [Problem<'p>], x: &'p [f64]) -> Vec<(&'p Problem<'p>, &'p [f64])> {
    problems
        .iter()
        .enumerate()
        .map(|(i, p)| (p, &x[6 * i..6 * i + 6]))
        .collect()
}

/// Whether no rod of `rods` (each problem at its unknowns) touches an obstacle: every
/// contact point's penetration delta = rho - d <= 0 (the penalty, and with it the
/// friction, is zero there) and nothing is stored in its contacts (`states`: a stored
/// elastic slip e != 0 needs a normal force, so it is checked first, without a pass).
fn untouched(rods: &[(&Problem, &[f64])], states: &[Option<FrictionState>]) -> bool {
    let stored = states.iter().flatten().any(|s| s.max_elastic_slip() > 0.0);
    !stored
        && rods.iter().all(|(p, x)| {
            let Some(obstacles) = p.rod.obstacles.as_deref() else {
                return true;
            };
            let rod = p.rod;
            let clear = |r: &[f64; 3], rho: f64| obstacles.iter().all(|o| rho <= o.distance(r).0);
            let mut touched = false;
            let mut hook = |node: NodeAt, y: &mut State<f64>| {
                let sec = &rod.sections[node.section];
                if !sec.rigid {
                    step_quadrature(rod, &p.coeffs, node, y, &mut |ys, s, _| {
                        touched |= !clear(&ys.r, sec.surface_radius(s));
                    });
                }
                touched
            };
            let tip = integrate_with(rod, &p.coeffs, p.base_state(x), &mut hook);
            let end = rod
                .sections
                .last()
                .map(|sec| clear(&tip.r, sec.surface_radius(sec.length)));
            !touched && end.unwrap_or(true)
        })
}

/// The increment loop shared by the free and the held tip and by systems of rods: from
/// each rod's `states` and the unknowns `x` (6 per rod first) at the path's start to the
/// legs' loads, in `steps` equal increments, each halved while `inner` fails (down to
/// 1/`sub_increments(steps)` of it). `inner(problems, t, guess)` is one increment's Newton solve: the rods'
/// problems at the loads of path parameter t, with the friction state of the last
/// converged increment, from `guess` (it may take the problems and must leave them in
/// place). After each converged increment the nodes are checked for crossing an obstacle
/// (rods named by index where `system`) and the states are advanced (`advance`).
pub(crate) fn follow<C: Reached>(
    legs: &[Leg],
    mut states: Vec<Option<FrictionState>>,
    mut x: Vec<f64>,
    steps: usize,
    system: bool,
    jumps: bool,
    mut inner: impl FnMut(&mut Vec<Problem>, f64, Vec<f64>) -> std::result::Result<C, (usize, f64)>,
) -> Result<PathEnd<C>> {
    let not_converged =
        |iterations, residual, load_factor, reason: String| SoftrodError::NotConverged {
            iterations,
            residual,
            load_factor,
            reason,
        };
    let loads_of = |t: f64| -> Vec<(Loads, f64)> {
        legs.iter().map(|l| loads_at(l.start, l.loads, t)).collect()
    };
    let (mut last, mut clear) = {
        let levels = loads_of(0.0);
        let problems = problems_at(legs, &levels, &states);
        let rods = rods_of(&problems, &x);
        let clear = jumps && untouched(&rods, &states);
        (contact::Sides::start(&rods), clear)
    };
    let check_crossing = !last.unchecked();
    // Contact-free stretches are jumped over: where no rod touches an obstacle, nothing is
    // stored in a contact (a point that lifts off forgets its slip), and the next
    // equilibrium does not depend on how the loads got there. So from an untouched state
    // on the grid an increment of `stride` requested ones is tried: one that lands
    // untouched is kept (and the stride doubles), one that lands touching an obstacle,
    // crosses one or fails is discarded and tried in half the stride, down to the single
    // increment, from which the path goes on as without jumps. The contact that follows is
    // therefore met in the same increments as without jumps (to the solver's tolerance).
    let mut stride = 1usize;
    // Where the path stands, in units of 1/sub of a requested increment: increment i,
    // position `at` in it. A failed increment is halved (level `depth`: length
    // sub >> depth), and after a success the length doubles again where the position
    // allows, so that sub-increments are dyadic and end on the requested grid: the path
    // depends on `steps` and on where Newton needed shorter increments, nothing else.
    let sub = sub_increments(steps);
    let mut i = 0usize;
    let mut at = 0u64;
    let mut depth = 0u32;
    let param = |i: usize, at: u64| -> f64 {
        if i >= steps {
            1.0
        } else {
            (i as f64 + at as f64 / sub as f64) / steps as f64
        }
    };
    let mut t = 0.0;
    // The last converged increment's move (for a secant predictor) and length.
    let mut last_move: Option<(Vec<f64>, f64)> = None;
    let mut iterations = 0;
    let mut levels = 0;
    loop {
        let len = sub >> depth;
        let span = if clear && depth == 0 && at == 0 {
            stride.min(steps - i)
        } else {
            1
        };
        let jump = span > 1;
        let (next_i, next_at) = if jump {
            (i + span, 0)
        } else if at + len >= sub {
            (i + 1, 0)
        } else {
            (i, at + len)
        };
        let target = param(next_i, next_at);
        let dt = target - t;
        let level = loads_of(target);
        let mut problems = problems_at(legs, &level, &states);
        let guess: Vec<f64> = match &last_move {
            Some((dx, dt_last)) => x
                .iter()
                .zip(dx)
                .map(|(x, d)| x + d * (dt / dt_last))
                .collect(),
            None => x.clone(),
        };
        // Newton with the exact Jacobian. The residual is continuous, its derivative
        // jumps where a point switches between stick and slip (semi-smooth: Newton
        // converges locally, and a failed increment is halved).
        let attempt = inner(&mut problems, target, guess);
        let failed = |it: usize, res: f64, why: &str| {
            not_converged(
                it,
                res,
                t,
                format!(
                    "the frictional load path failed at {:.4} of the path: {why}, even in an increment of {:.3e} (1/{sub} of one of the {} requested): the stick/slip switches are too sharp for Newton there; a softer penalty stiffness (whose elastic slip mu delta is longer; raise the tolerance with it) or more max_iter may help",
                    t, dt, steps
                ),
            )
        };
        levels += 1;
        match attempt {
            Ok(c) => {
                iterations += c.iterations();
                let cx = c.x();
                let rods = rods_of(&problems, &cx);
                // The nodes where this increment lands, kept as the reference of the next
                // crossing check once the increment is accepted (not for a discarded jump).
                let mut landed = None;
                if check_crossing {
                    let shape = last.at(&rods);
                    if let Some(cr) = last.crossing(&shape, &rods, system) {
                        if jump {
                            stride = span / 2;
                            continue;
                        }
                        if len == 1 || dt <= MIN_CROSSING_STEP {
                            return Err(contact::crossing_error(cr, Some(dt)));
                        }
                        depth += 1;
                        continue;
                    }
                    landed = Some(shape);
                }
                let mut touchdown = false;
                let next: Vec<Option<FrictionState>> = rods
                    .iter()
                    .zip(&states)
                    .map(|((p, xi), s)| {
                        let (s, obstacles) = (s.as_ref()?, p.rod.obstacles.as_deref()?);
                        let (next, landed) = advance(p, xi, s, obstacles);
                        touchdown |= landed;
                        Some(next)
                    })
                    .collect();
                let lands_clear = jumps && untouched(&rods, &next);
                drop(rods);
                if jump && !lands_clear {
                    stride = span / 2;
                    continue;
                }
                // A point that lands in an increment is anchored as if it moved straight
                // over it (`Obstacle::stick_load`); its path before landing is not
                // resolved inside the increment, so a landing increment is never longer
                // than the default path's (1/DEFAULT_FRICTION_STEPS of the path): a coarse
                // request that lands in one increment would otherwise count a flight that
                // turned back before touching as slip, and get the friction's sign wrong.
                if touchdown && dt > LANDING_STEP && len > 1 {
                    depth += 1;
                    continue;
                }
                if let Some(shape) = landed {
                    last = shape;
                }
                if lands_clear {
                    stride = (2 * span).min(steps);
                } else {
                    stride = 1;
                }
                clear = lands_clear;
                if target >= 1.0 {
                    return Ok(PathEnd {
                        last: c,
                        states,
                        next,
                        x: cx,
                        iterations,
                        levels,
                    });
                }
                last_move = Some((cx.iter().zip(&x).map(|(a, b)| a - b).collect(), dt));
                x = cx;
                states = next;
                t = target;
                (i, at) = (next_i, next_at);
                // Back to the longer increment once the position is on its grid.
                if depth > 0 && at % (2 * len) == 0 {
                    depth -= 1;
                }
            }
            Err((it, res)) => {
                iterations += it;
                if jump {
                    stride = span / 2;
                    continue;
                }
                if len == 1 {
                    return Err(failed(iterations, res, "Newton did not converge"));
                }
                depth += 1;
            }
        }
    }
}

/// The finest subdivision of a requested increment (a power of two, so that halvings stay
/// dyadic and end on the requested grid): 1/SUB of it, and, for a path coarser than the
/// default, fine enough that the smallest sub-increment is at most 1/SUB of the default
/// path's increment. Where Newton needs short increments is set by the contact (e.g.
/// just after a point lands in the penalty's smoothing zone, where the bundled finger on
/// a table with mu = 0.5 needs 1.6e-4 to 1e-3 of the path whatever the request), not by
/// how many increments were requested; a floor relative to a coarse request (1/1024 of a
/// third of the path is 3.3e-4) would refuse paths that finer requests solve.
fn sub_increments(steps: usize) -> u64 {
    let coarse = DEFAULT_FRICTION_STEPS.div_ceil(steps.max(1)) as u64;
    SUB * coarse.next_power_of_two()
}

/// The scaled residual and its exact Jacobian (dual numbers) of the frictional problem
/// at the unknowns `x` (6) of `loads`, with the friction state of `path` as the last
/// converged increment's: exposed for tests against finite differences.
#[doc(hidden)]
pub fn residual_and_jacobian(
    rod: &Rod,
    loads: &Loads,
    path: &FrictionPath,
    x: &[f64; 6],
) -> ([f64; 6], [[f64; 6]; 6]) {
    let p = Problem::with_friction(rod, loads, 1.0, &path.state);
    let (r, j) = p.eval_jac(x);
    (
        r,
        std::array::from_fn(|i| std::array::from_fn(|k| j[(i, k)])),
    )
}

/// [`residual_and_jacobian`] of a tip held by `constraint` (pinned or clamped) at its
/// prescribed pose: the residual of `constraint::Held` (the constrained solve's, the
/// friction loads of `path`'s state in its dual-number pass), for tests against finite
/// differences.
#[doc(hidden)]
pub fn held_residual_and_jacobian(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    path: &FrictionPath,
    x: &[f64; 6],
) -> Result<([f64; 6], [[f64; 6]; 6])> {
    constraint.validate()?;
    if matches!(constraint, TipConstraint::Free) {
        return Err(SoftrodError::invalid(
            "constraint",
            "free",
            "must be pinned or clamped (a free tip: friction::residual_and_jacobian)",
        ));
    }
    let p = Problem::with_friction(rod, loads, 1.0, &path.state);
    let eq = Held {
        p: &p,
        pose: Pose::along(constraint, &[0.0; 3], &IDENTITY, 1.0),
    };
    let (r, j) = constraint::Equations::eval_jac(&eq, x);
    Ok((
        std::array::from_fn(|i| r[i]),
        std::array::from_fn(|i| std::array::from_fn(|k| j[(i, k)])),
    ))
}
