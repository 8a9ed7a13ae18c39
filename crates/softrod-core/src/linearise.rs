//! The linearised dynamics of the rod about a static equilibrium:
//!   M q'' + D q' + K q = B u,
//! with q the displacement dr and small rotation dtheta (world frame, dR = [dtheta]x R) of
//! n nodes along the rod (the last one the tip), u the changes of the chamber pressures, of
//! the dead tip force and moment and of the tendon tensions.
//!
//! Discretisation (a Ritz method with the rod's own static deflection shapes):
//! - K is the exact static tangent condensed to the nodes: K = C^-1 with C the flexibility,
//!   the derivative of the node poses with respect to dead point forces and moments at the
//!   nodes, by one dual pass per node (point loads enter as jumps of n and m) and the
//!   implicit function theorem on the shooting residual (`crate::jacobian`). It contains
//!   everything the equilibrium does: the material law with its pressure-dependent
//!   coefficients, the prestress of gravity and pressure, the tip body's moment arm.
//! - Between the nodes the rod deforms as under the node loads, so the displacement field is
//!   dr(s) = Phi_r(s) K q and the strain field (dv, du)(s) = Psi(s) K q with Phi, Psi the
//!   recorded derivatives at every integration node. These are the shape functions of M and
//!   D (exact static shapes, like Hermite cubics for an Euler beam):
//!   M = int Phi^T diag(rho A I, R rho J R^T) Phi ds (+ the tip body), and
//!   D = int Psi^T diag(B_se, B_bt) Psi ds for Kelvin-Voigt damping (paper 000 eq. 8:
//!   B = tau K_0 with K_0 the section's stiffness at the current pressure, or the section's
//!   damping diagonals), both by the trapezoidal rule on the integration nodes (Simpson on
//!   rigid parts, exact there).
//! - B: pressure and tension columns K dq/dp (a pressure change shifts the rest strains, a
//!   tension change the tendon law's strains, so its static response K^-1 B equals the
//!   equilibrium's derivative); tip load columns are unit generalised forces at the tip node.
//!
//! Tendons, reference shapes and tapered sections enter K, Phi and Psi through the static
//! model; a tapered section's inertia and damping are evaluated at each quadrature point
//! (`section_inertia_at`, `Coeffs::at`), as the dynamics evaluates them at its stages.
//!
//! This construction uses only the static model and the section inertia, so it does not
//! depend on how the dynamic solver discretises space and time. An equilibrium that statics
//! solved by collocation (a long, soft rod) gets the same responses from the collocation
//! equations ([`collocation`]).
//!
//! A held tip ([`linearise_held`]) changes the static model: six shooting unknowns (the base
//! force too) and the held tip's residual in the implicit differentiation. A clamped tip is
//! no coordinate (the nodes lie between the clamps), adds no tip-body mass and has zero
//! tip-load columns. A pinned tip keeps its three small rotations as coordinates (the tip
//! node is the last, its displacement rows are not coordinates): the generalised loads
//! there are the three moments only, the tip body adds its inertia about the pin, and the
//! tip force columns are zero (the pin takes it).

mod collocation;
pub mod system;

use crate::dynamics::section_inertia_at;
use crate::error::{Result, SoftrodError};
use crate::jacobian::{dual_coeffs_from, pose_derivative, singular, Input};
use crate::jet::Jet;
use crate::ode::{advance, integrate_with, resolve_stretch, strains, Coeffs, Loads, NodeAt, State};
use crate::rod::{inverse3, Rod, Section};
use crate::spec::Frame;
use crate::statics::constraint::{tip_residual_under, TipConstraint};
use crate::statics::tangent::solve_tangent;
use crate::statics::{Problem, Solution};
use nalgebra::{DMatrix, DVector, Matrix3};

/// Most nodes of a linearisation (6 coordinates each).
pub const MAX_NODES: usize = 200;

/// The linearised system about an equilibrium (SI; q = (dr_1, dtheta_1, ..., dr_n,
/// dtheta_n); with a pinned tip the last node, the tip, has only dtheta_n).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSystem {
    /// Arc length of every node, m (the last is the tip, except with a clamped tip).
    pub nodes: Vec<f64>,
    pub mass: DMatrix<f64>,
    pub damping: DMatrix<f64>,
    pub stiffness: DMatrix<f64>,
    /// Columns: pressures (Pa, one per channel), tip force (N, x y z), tip moment (N m),
    /// tensions (N, one per tendon channel), and for a rod with a stiffness-mapped section
    /// its factors sigma (1; at fixed pressures: the caller adds them times d sigma / d p to
    /// the pressures' columns).
    pub input: DMatrix<f64>,
}

/// The integration nodes that end a step: (section, step) and arc length.
fn step_nodes(rod: &Rod) -> Vec<(usize, usize, f64)> {
    let mut out = Vec::new();
    for (i, sec) in rod.sections.iter().enumerate() {
        let h = sec.length / sec.steps as f64;
        for k in 1..=sec.steps {
            out.push((i, k, sec.s_start + h * k as f64));
        }
    }
    out
}

/// `n` nodes spread evenly over the integration nodes, the tip last.
pub fn choose_nodes(rod: &Rod, n: usize) -> Result<Vec<(usize, usize, f64)>> {
    let all = step_nodes(rod);
    if n == 0 || n > all.len().min(MAX_NODES) {
        return Err(SoftrodError::invalid(
            "nodes",
            n,
            format!(
                "must lie in 1..={} (the design has {} integration steps; raise numerics steps for more)",
                all.len().min(MAX_NODES),
                all.len()
            ),
        ));
    }
    let t = all.len();
    Ok((1..=n).map(|k| all[(k * t).div_ceil(n) - 1]).collect())
}

/// `n` nodes spread evenly over the integration nodes inside the rod, for a clamped tip (the
/// tip is not a coordinate): the k-th at step k T / (n + 1) of the T steps, so that they
/// sit symmetrically between the two clamped ends.
pub fn choose_inner_nodes(rod: &Rod, n: usize) -> Result<Vec<(usize, usize, f64)>> {
    let all = step_nodes(rod);
    let t = all.len();
    if n == 0 || n > (t - 1).min(MAX_NODES) {
        return Err(SoftrodError::invalid(
            "nodes",
            n,
            format!(
                "must lie in 1..={} with a clamped tip (the design has {t} integration steps, \
                 the tip's not a coordinate; raise numerics steps for more)",
                (t - 1).min(MAX_NODES)
            ),
        ));
    }
    Ok((1..=n).map(|k| all[k * t / (n + 1) - 1]).collect())
}

/// What one pass records on one step interval [a, b]: pose and strains at both ends
/// (strains as right limit at a and left limit at b, since point loads make them jump).
struct Interval<D> {
    section: usize,
    a: f64,
    b: f64,
    start: State<D>,
    mid: State<D>,
    end: State<D>,
    strain_a: [D; 6],
    strain_m: [D; 6],
    strain_b: [D; 6],
}

impl<const N: usize> Interval<Jet<N>> {
    /// Section, [a, b] and the rotations' values at a, the midpoint and b.
    fn meta(&self) -> Meta {
        let value = |st: &State<Jet<N>>| st.rot.map(|r| r.map(|v| v.re));
        (
            self.section,
            self.a,
            self.b,
            [value(&self.start), value(&self.mid), value(&self.end)],
        )
    }

    /// The start, midpoint and end with their strains.
    #[allow(clippy::type_complexity)]
    fn ends(&self) -> [(&State<Jet<N>>, &[Jet<N>; 6]); 3] {
        [
            (&self.start, &self.strain_a),
            (&self.mid, &self.strain_m),
            (&self.end, &self.strain_b),
        ]
    }
}

/// The tip the equilibrium is linearised with: free under dead loads without obstacles
/// (three shooting unknowns, the base moment; `Jet<9>` carries them and a node's point
/// force and moment), or with six unknowns (the base force too; `Jet<12>`): a free tip
/// under follower loads or pressed on obstacles (`TipConstraint::Free`: the base force
/// depends on the shape), or a held one: clamped, so the tip is not a coordinate (it does
/// not move), or pinned, so only its rotation is.
#[derive(Clone, Copy)]
enum Tip<'a> {
    Free,
    Six(&'a TipConstraint),
}

impl Tip<'_> {
    fn unknowns(&self) -> usize {
        match self {
            Tip::Free => 3,
            Tip::Six(_) => 6,
        }
    }

    fn pinned(&self) -> bool {
        matches!(self, Tip::Six(TipConstraint::Pinned { .. }))
    }

    fn clamped(&self) -> bool {
        matches!(self, Tip::Six(TipConstraint::Clamped { .. }))
    }

    /// The shooting residual at the tip (3 or 6 rows) under the tip loads of `loads` (in
    /// the design's tip frame: a follower load turns with the tip).
    fn residual<const N: usize>(
        &self,
        problem: &Problem,
        loads: &Loads,
        tip: &State<Jet<N>>,
    ) -> Vec<Jet<N>> {
        match self {
            Tip::Free => problem.residual_of_tip::<Jet<N>, 3>(tip).to_vec(),
            Tip::Six(constraint) => {
                let f = loads.tip_force.map(Jet::from);
                let m = loads.tip_moment.map(Jet::from);
                tip_residual_under(problem, constraint, tip, &f, &m).to_vec()
            }
        }
    }
}

/// Which pose rows (dr, dtheta) of each node are coordinates of q: all six, but the
/// rotation only at a pinned tip (the last node). A coordinate's generalised load is its
/// work conjugate: a point force for dr, a point moment for dtheta.
struct Layout {
    rows: Vec<std::ops::Range<usize>>,
    offset: Vec<usize>,
    size: usize,
}

impl Layout {
    fn new(n_nodes: usize, tip: Tip) -> Self {
        let rows: Vec<_> = (0..n_nodes)
            .map(|k| {
                if k + 1 == n_nodes && tip.pinned() {
                    3..6
                } else {
                    0..6
                }
            })
            .collect();
        let mut offset = Vec::with_capacity(n_nodes);
        let mut size = 0;
        for r in &rows {
            offset.push(size);
            size += r.len();
        }
        Layout { rows, offset, size }
    }

    /// (node, pose row, coordinate index) of every coordinate, in order.
    fn coordinates(&self) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        self.rows
            .iter()
            .enumerate()
            .flat_map(move |(k, r)| r.clone().map(move |j| (k, j, self.offset[k] + j - r.start)))
    }
}

/// Strains at local arc length `s` of section `sec` (zero in a rigid one).
fn strain6<D: crate::jet::StateScalar<f64>>(
    sec: &Section,
    y: &State<D>,
    c: &Coeffs<f64>,
    s: f64,
) -> [D; 6] {
    if sec.rigid {
        return [D::from(0.0); 6];
    }
    let (v, u) = strains(sec, y, c, s);
    [v[0], v[1], v[2], u[0], u[1], u[2]]
}

/// One pass with a point force and moment at node `at` (section, step) seeded as directions
/// nx..nx + 6 after the nx shooting unknowns x: the tip state and every interval.
fn load_pass<const N: usize>(
    problem: &Problem,
    rod: &Rod,
    x: &[f64],
    at: (usize, usize),
) -> (State<Jet<N>>, Vec<Interval<Jet<N>>>) {
    let nx = x.len();
    let xd: Vec<Jet<N>> = x
        .iter()
        .enumerate()
        .map(|(i, v)| Jet::variable(*v, i))
        .collect();
    let mut y0 = problem.base_state(&xd);
    if nx == 3 {
        for j in 0..3 {
            // The point force is carried by everything inboard: n(0) grows by it. (With six
            // unknowns n(0) is one of them.)
            y0.n[j].eps[nx + j] = 1.0;
        }
    }
    let mut intervals: Vec<Interval<Jet<N>>> = Vec::new();
    type Open<D> = (usize, f64, State<D>, [D; 6], State<D>, [D; 6]);
    let mut open: Option<Open<Jet<N>>> = None;
    let coeffs = &problem.coeffs;
    let end = integrate_with(rod, coeffs, y0, &mut |node: NodeAt, y| {
        let sec = &rod.sections[node.section];
        let c = &coeffs[node.section];
        if node.step > 0 {
            if let Some((section, a, start, strain_a, mid, strain_m)) = open.take() {
                intervals.push(Interval {
                    section,
                    a,
                    b: node.s,
                    start,
                    mid,
                    end: *y,
                    strain_a,
                    strain_m,
                    strain_b: strain6(sec, y, c, node.s - sec.s_start),
                });
            }
        }
        let mut changed = false;
        if (node.section, node.step) == at {
            for j in 0..3 {
                y.n[j].eps[nx + j] -= 1.0;
                y.m[j].eps[nx + 3 + j] -= 1.0;
            }
            resolve_stretch(y, c);
            changed = true;
        }
        if node.step < sec.steps {
            // The interval starting here, after the jump (right limits of the strains), and
            // its midpoint by half a step (for Simpson's rule).
            let h = if sec.rigid {
                sec.length
            } else {
                sec.length / sec.steps as f64
            };
            let mid = advance(rod, coeffs, node, y, 0.5 * h);
            open = Some((
                node.section,
                node.s,
                *y,
                strain6(sec, y, c, node.s - sec.s_start),
                mid,
                strain6(sec, &mid, c, node.s - sec.s_start + 0.5 * h),
            ));
        }
        changed
    });
    (end, intervals)
}

/// Linearise the dynamics at the converged equilibrium `sol` of `loads` with `n_nodes`
/// nodes (see the module docs). Under follower loads or on obstacles the base force is a
/// shooting unknown too (six, as `sol` has them) and the tip's balance is its residual: a
/// follower load turns with the rod, so K is not symmetric (no potential: a follower
/// compression can make the equilibrium flutter, as Beck's column does), and the penalty
/// of the contact law adds its stiffness. A frictional equilibrium is refused: the
/// stick/slip switch has no derivative.
pub fn linearise(rod: &Rod, loads: &Loads, sol: &Solution, n_nodes: usize) -> Result<LinearSystem> {
    refuse_friction(sol)?;
    let nodes = choose_nodes(rod, n_nodes)?;
    if sol.collocation.is_some() {
        // Solved by collocation (a free tip under dead loads): the responses come from the
        // collocation equations, since shooting passes from x would leave the equilibrium.
        let layout = Layout::new(nodes.len(), Tip::Free);
        let responses = collocation::responses(rod, loads, sol, &nodes, &layout)?;
        return assemble(rod, loads, sol, &nodes, &layout, Tip::Free, responses);
    }
    if loads.base_force_unknown(rod) {
        let x = six_unknowns(sol, "a free tip under follower loads or on obstacles")?;
        return linearise_at_nodes::<12>(
            rod,
            loads,
            sol,
            &x,
            &nodes,
            Tip::Six(&TipConstraint::Free),
        );
    }
    let x = crate::jacobian::unknowns3(sol)?;
    linearise_at_nodes::<9>(rod, loads, sol, &x, &nodes, Tip::Free)
}

/// Linearise the dynamics at the converged equilibrium `sol` of `loads` whose tip is held
/// by `constraint`. The stiffness is the held rod's (six shooting unknowns, the tip's
/// residual). Clamped: the tip does not move, so its pose is not a coordinate; the `n_nodes`
/// nodes spread over the rest of the rod (`choose_inner_nodes`), the tip body adds no mass,
/// and a tip load goes whole into the clamp (zero input columns). Pinned: the nodes are
/// spread as for a free tip (`choose_nodes`, the tip last), the tip's three small rotations
/// are its only coordinates, the tip body adds its inertia about the pin, and a tip force
/// goes into the pin (zero columns; the tip moment's are unit moments at the tip). Follower
/// loads and frictionless obstacles enter as in [`linearise`].
pub fn linearise_held(
    rod: &Rod,
    loads: &Loads,
    constraint: &TipConstraint,
    sol: &Solution,
    n_nodes: usize,
) -> Result<LinearSystem> {
    if let TipConstraint::Free = constraint {
        return Err(SoftrodError::invalid(
            "tip_constraint",
            "free",
            "the held linearisation takes a clamped or pinned tip; a free tip: linearise",
        ));
    }
    refuse_friction(sol)?;
    let x = six_unknowns(sol, "a held tip's equilibrium")?;
    let nodes = match constraint {
        TipConstraint::Pinned { .. } => choose_nodes(rod, n_nodes)?,
        _ => choose_inner_nodes(rod, n_nodes)?,
    };
    linearise_at_nodes::<12>(rod, loads, sol, &x, &nodes, Tip::Six(constraint))
}

/// The six shooting unknowns of `sol`, which must be `what`.
fn six_unknowns(sol: &Solution, what: &str) -> Result<[f64; 6]> {
    <[f64; 6]>::try_from(sol.x.as_slice()).map_err(|_| {
        SoftrodError::invalid(
            "solution",
            format!("{} shooting unknowns", sol.x.len()),
            format!("{what} (six shooting unknowns, the base force and moment) is needed here"),
        )
    })
}

/// A frictional equilibrium has no linearisation: its friction depends on the load path
/// and the stick/slip switch has no derivative.
fn refuse_friction(sol: &Solution) -> Result<()> {
    if sol.friction.is_some() {
        return Err(SoftrodError::invalid(
            "solution",
            "a frictional equilibrium",
            "friction makes the equilibrium depend on its load path and the stick/slip \
             switch has no derivative, so it has no linearisation (obstacles without \
             friction have one)",
        ));
    }
    Ok(())
}

/// The static model's responses a linearisation is assembled from ([`assemble`]), in load
/// coordinates (one column per coordinate's conjugate load, [`Layout`]).
struct Responses {
    /// The flexibility C (nq x nq): every coordinate's derivative with respect to every
    /// coordinate's conjugate load.
    flex: DMatrix<f64>,
    /// Per integration interval: section, [a, b] and the rotations at a, the midpoint, b.
    meta: Vec<Meta>,
    /// The pose (phi) and strain (psi) derivatives (6 x nq) at every interval's start
    /// (right limit), midpoint and end (left limit).
    phi: Vec<[DMatrix<f64>; 3]>,
    psi: Vec<[DMatrix<f64>; 3]>,
    /// The coordinates' derivatives (nq x inputs) with respect to the pressures, the
    /// tensions and a mapped rod's factors sigma ([`Inputs`]).
    dq: DMatrix<f64>,
}

/// The inputs whose response columns B carries as K dq/du: the pressures, the tensions and,
/// for a rod with a stiffness-mapped section, its three factors sigma.
struct Inputs {
    nc: usize,
    nt: usize,
    ns: usize,
}

impl Inputs {
    fn of(rod: &Rod) -> Self {
        // A stiffness-mapped rod's factors sigma: the caller composes them with its map's
        // d sigma / d p (the pressures' columns are partial derivatives at fixed sigma).
        let ns = if rod.sections.iter().any(|s| s.law.stiffness_map) {
            3
        } else {
            0
        };
        Inputs {
            nc: rod.n_channels,
            nt: rod.n_tendons,
            ns,
        }
    }

    fn len(&self) -> usize {
        self.nc + self.nt + self.ns
    }

    fn input(&self, u: usize) -> Input {
        if u < self.nc {
            Input::Pressure(u)
        } else if u < self.nc + self.nt {
            Input::Tension(u - self.nc)
        } else {
            Input::StiffnessScale(u - self.nc - self.nt)
        }
    }
}

/// The linearisation with nodes `nodes` and the `tip` of `x`'s unknowns, in `Jet<N>` (N =
/// unknowns + 6).
fn linearise_at_nodes<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    x: &[f64],
    nodes: &[(usize, usize, f64)],
    tip: Tip,
) -> Result<LinearSystem> {
    let layout = Layout::new(nodes.len(), tip);
    let responses = shooting_responses::<N>(rod, loads, sol, x, nodes, &layout, tip)?;
    assemble(rod, loads, sol, nodes, &layout, tip, responses)
}

/// [`Responses`] by shooting passes from the unknowns `x`: one pass per node with its point
/// force and moment seeded, the implicit function theorem on the shooting residual.
fn shooting_responses<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    x: &[f64],
    nodes: &[(usize, usize, f64)],
    layout: &Layout,
    tip: Tip,
) -> Result<Responses> {
    let nx = tip.unknowns();
    debug_assert_eq!(nx + 6, N);
    let nq = layout.size;
    let problem = Problem::new(rod, loads, 1.0);
    // Per load node k: derivatives of every interval quantity w.r.t. its load components
    // (the coordinates' conjugates). phi[interval][end] is (6, nq) for the pose and psi for
    // the strains.
    let mut flex = DMatrix::<f64>::zeros(nq, nq);
    let mut meta: Vec<Meta> = Vec::new();
    let mut phi: Vec<[DMatrix<f64>; 3]> = Vec::new();
    let mut psi: Vec<[DMatrix<f64>; 3]> = Vec::new();
    for (k, &(sec, step, _)) in nodes.iter().enumerate() {
        let (end, intervals) = load_pass::<N>(&problem, rod, x, (sec, step));
        let g = tip.residual(&problem, loads, &end);
        let gx = DMatrix::from_fn(nx, nx, |i, j| g[i].eps[j]);
        let lu = gx.lu();
        // dx / d load_j for the 6 load directions.
        let mut dx = vec![vec![0.0; nx]; 6];
        for (j, dxj) in dx.iter_mut().enumerate() {
            let rhs = DVector::from_fn(nx, |i, _| -g[i].eps[nx + j]);
            let d = solve_tangent(&lu, &rhs, || singular(sol))?;
            dxj.copy_from_slice(d.as_slice());
        }
        let total6 = |partial: &dyn Fn(usize) -> [f64; 6]| -> [[f64; 6]; 6] {
            let px: Vec<[f64; 6]> = (0..nx).map(partial).collect();
            std::array::from_fn(|j| {
                let pj = partial(nx + j);
                std::array::from_fn(|r| pj[r] + (0..nx).map(|i| px[i][r] * dx[j][i]).sum::<f64>())
            })
        };
        if k == 0 {
            meta = intervals.iter().map(Interval::meta).collect();
            (phi, psi) = zero_fields(meta.len(), nq);
        }
        for (m, iv) in intervals.iter().enumerate() {
            for (e, (st, sn)) in iv.ends().iter().enumerate() {
                let dpose = total6(&|dir| pose_derivative(st, dir));
                let dstrain = total6(&|dir| std::array::from_fn(|r| sn[r].eps[dir]));
                record(layout, k, &dpose, &dstrain, &mut phi[m][e], &mut psi[m][e]);
            }
        }
        fill_flexibility(rod, nodes, layout, k, &meta, &phi, &mut flex);
    }
    let dq = shooting_input_response::<N>(rod, loads, sol, x, nodes, layout, tip)?;
    Ok(Responses {
        flex,
        meta,
        phi,
        psi,
        dq,
    })
}

/// Zero pose and strain derivative fields for `n` intervals and `nq` coordinates.
type Fields = Vec<[DMatrix<f64>; 3]>;
fn zero_fields(n: usize, nq: usize) -> (Fields, Fields) {
    let z = || [(); 3].map(|_| DMatrix::zeros(6, nq));
    ((0..n).map(|_| z()).collect(), (0..n).map(|_| z()).collect())
}

/// Store load node `k`'s pose and strain derivatives (`dpose[j]`, `dstrain[j]` for its load
/// component j) in the columns of its coordinates.
fn record(
    layout: &Layout,
    k: usize,
    dpose: &[[f64; 6]; 6],
    dstrain: &[[f64; 6]; 6],
    phi: &mut DMatrix<f64>,
    psi: &mut DMatrix<f64>,
) {
    for (_, j, col) in layout.coordinates().filter(|c| c.0 == k) {
        for r in 0..6 {
            phi[(r, col)] = dpose[j][r];
            psi[(r, col)] = dstrain[j][r];
        }
    }
}

/// The flexibility's columns of load node `k`: the node poses (the end of the interval that
/// ends at each node) that are coordinates.
fn fill_flexibility(
    rod: &Rod,
    nodes: &[(usize, usize, f64)],
    layout: &Layout,
    k: usize,
    meta: &[Meta],
    phi: &[[DMatrix<f64>; 3]],
    flex: &mut DMatrix<f64>,
) {
    for (a, r, row) in layout.coordinates() {
        let s_a = nodes[a].2;
        let m = meta
            .iter()
            .position(|iv| (iv.2 - s_a).abs() <= 1e-12 * rod.length)
            .expect("every node ends an interval");
        for (_, _, col) in layout.coordinates().filter(|c| c.0 == k) {
            flex[(row, col)] = phi[m][2][(r, col)];
        }
    }
}

/// The linear system from the static model's responses: K = C^-1, M and D in load
/// coordinates turned by K, the tip body, and B.
fn assemble(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    nodes: &[(usize, usize, f64)],
    layout: &Layout,
    tip: Tip,
    responses: Responses,
) -> Result<LinearSystem> {
    let nq = layout.size;
    let Responses {
        flex,
        meta,
        phi,
        psi,
        dq,
    } = responses;
    let stiffness = flex.try_inverse().ok_or_else(|| singular(sol))?;
    let problem = Problem::new(rod, loads, 1.0);
    // Mass and damping in load coordinates, then K^T (.) K.
    let (gm, gd) = interval_gram(rod, &problem, &meta, &phi, &psi, nq);
    // The tip body: mass m_t at c_w = R(L) c from the tip node, inertia along the tip frame.
    let rot_l = meta.last().expect("at least one interval").3[2];
    let tip_block = tip_body_block(rod, &rot_l, [0.0; 3]);
    let kt = stiffness.transpose();
    // K^T G K is symmetric; symmetrise away the round-off of the product.
    let sym = |a: DMatrix<f64>| (&a + a.transpose()) * 0.5;
    let mut mass = sym(&kt * gm * &stiffness);
    let damping = sym(&kt * gd * &stiffness);
    // The tip body rides on the tip node: all of it on a free tip, its rotation about a pin
    // (the block's rotational part, J_w - m_t [c_w]x^2), none on a clamp.
    let held = if tip.pinned() {
        3..6
    } else if tip.clamped() {
        0..0
    } else {
        0..6
    };
    let o = nq - held.len();
    for (a, i) in held.clone().enumerate() {
        for (b, j) in held.clone().enumerate() {
            mass[(o + a, o + b)] += tip_block[(i, j)];
        }
    }
    let input = input_matrix(rod, loads, nodes, layout, &stiffness, &dq, tip, &rot_l);
    Ok(LinearSystem {
        nodes: nodes.iter().map(|n| n.2).collect(),
        mass,
        damping,
        stiffness,
        input,
    })
}

/// Per interval of a rod: section, [a, b] and the rotation at a, the midpoint and b.
type Meta = (usize, f64, f64, [[[f64; 3]; 3]; 3]);

/// The mass and damping Gram matrices int Phi^T M_s Phi ds and int Psi^T B Psi ds of one
/// rod in load coordinates (nq columns), by Simpson's rule on its intervals (exact on rigid
/// parts, whose motion is linear in s).
fn interval_gram(
    rod: &Rod,
    problem: &Problem,
    meta: &[Meta],
    phi: &[[DMatrix<f64>; 3]],
    psi: &[[DMatrix<f64>; 3]],
    nq: usize,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let tau = rod.spec.dynamics.damping_time;
    let mut gm = DMatrix::<f64>::zeros(nq, nq);
    let mut gd = DMatrix::<f64>::zeros(nq, nq);
    for (m, &(sec, a, b, rots)) in meta.iter().enumerate() {
        let w = [(b - a) / 6.0, 4.0 * (b - a) / 6.0, (b - a) / 6.0];
        let local = [a, 0.5 * (a + b), b].map(|s| s - rod.sections[sec].s_start);
        let mass_at = |rot: &[[f64; 3]; 3], s: f64| -> DMatrix<f64> {
            let inertia = section_inertia_at(rod, sec, s);
            let mut ms = DMatrix::zeros(6, 6);
            for i in 0..3 {
                ms[(i, i)] = inertia.rho_a;
            }
            for i in 0..3 {
                for j in 0..3 {
                    ms[(3 + i, 3 + j)] = (0..3)
                        .map(|k| rot[i][k] * inertia.rho_j[k] * rot[j][k])
                        .sum();
                }
            }
            ms
        };
        for e in 0..3 {
            let ms = mass_at(&rots[e], local[e]);
            gm += phi[m][e].transpose() * &ms * &phi[m][e] * w[e];
        }
        if rod.sections[sec].rigid {
            continue;
        }
        for e in 0..3 {
            let coeffs = problem.coeffs[sec].at(&rod.sections[sec], local[e]);
            let bmat = damping_matrix(rod, &coeffs, sec, local[e], tau);
            gd += psi[m][e].transpose() * &bmat * &psi[m][e] * w[e];
        }
    }
    (gm, gd)
}

/// The rigid-body mass matrix (6 x 6, world) of the rod's tip body about a point at
/// `lever` (world) from the tip, for that point's displacement and small rotation: mass
/// m_t at c_w = lever + R(L) c, inertia along the tip frame `rot_l`:
/// [[m I, -m [c_w]x], [m [c_w]x, J_w - m [c_w]x^2]].
fn tip_body_block(rod: &Rod, rot_l: &[[f64; 3]; 3], lever: [f64; 3]) -> DMatrix<f64> {
    let body = &rod.spec.tip;
    let cw: [f64; 3] = std::array::from_fn(|i| {
        lever[i]
            + (0..3)
                .map(|k| rot_l[i][k] * body.com_offset[k])
                .sum::<f64>()
    });
    let jw = Matrix3::from_fn(|i, j| {
        (0..3)
            .map(|k| rot_l[i][k] * body.inertia[k] * rot_l[j][k])
            .sum()
    });
    rigid_block(body.mass, &cw, &jw)
}

/// The mass matrix (6 x 6) of a rigid body of mass `m` whose centre of mass lies at `c`
/// from the reference point, with inertia `jw` about its centre of mass (world), for the
/// point's displacement and small rotation: [[m I, -m [c]x], [m [c]x, J_w - m [c]x^2]].
fn rigid_block(m: f64, c: &[f64; 3], jw: &Matrix3<f64>) -> DMatrix<f64> {
    let skew = Matrix3::new(0.0, -c[2], c[1], c[2], 0.0, -c[0], -c[1], c[0], 0.0);
    let mut b = DMatrix::<f64>::zeros(6, 6);
    let ct = -skew * m;
    let rr = jw - skew * skew * m;
    for i in 0..3 {
        b[(i, i)] = m;
        for j in 0..3 {
            b[(i, 3 + j)] = ct[(i, j)];
            b[(3 + i, j)] = -ct[(i, j)];
            b[(3 + i, 3 + j)] = rr[(i, j)];
        }
    }
    b
}

/// Kelvin-Voigt damping of a section at local arc length `s` in the body frame (6 x 6): the
/// given diagonals, else tau times the section's stiffness there at this pressure (the
/// inverse of its compliances `c`, the section's law at `s`).
fn damping_matrix(rod: &Rod, c: &Coeffs<f64>, sec: usize, s: f64, tau: f64) -> DMatrix<f64> {
    let mut b = DMatrix::zeros(6, 6);
    match section_inertia_at(rod, sec, s).damping {
        Some((se, bt)) => {
            for i in 0..3 {
                b[(i, i)] = se[i];
                b[(3 + i, 3 + i)] = bt[i];
            }
        }
        None => {
            let kbt = inverse3(&c.c_bt).unwrap_or([[f64::NAN; 3]; 3]);
            for i in 0..3 {
                b[(i, i)] = tau / c.c_se[i];
                for j in 0..3 {
                    b[(3 + i, 3 + j)] = tau * kbt[i][j];
                }
            }
        }
    }
    b
}

/// The coordinates' derivatives with respect to the pressures, the tensions and a mapped
/// rod's factors sigma ([`Inputs`]), by shooting passes with those inputs seeded (after the
/// unknowns x) and the implicit function theorem on the tip's residual.
fn shooting_input_response<const N: usize>(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    x: &[f64],
    nodes: &[(usize, usize, f64)],
    layout: &Layout,
    tip: Tip,
) -> Result<DMatrix<f64>> {
    let inputs = Inputs::of(rod);
    let nx = tip.unknowns();
    let mut dq = DMatrix::<f64>::zeros(layout.size, inputs.len());
    let problem = Problem::new(rod, loads, 1.0);
    for chunk in (0..inputs.len()).collect::<Vec<_>>().chunks(6) {
        let seeded: Vec<Input> = chunk.iter().map(|&u| inputs.input(u)).collect();
        let coeffs = dual_coeffs_from::<N>(rod, loads, &seeded, nx);
        let xd: Vec<Jet<N>> = x
            .iter()
            .enumerate()
            .map(|(i, v)| Jet::variable(*v, i))
            .collect();
        let y0 = problem.base_state(&xd);
        let mut at_nodes: Vec<State<Jet<N>>> = Vec::with_capacity(nodes.len());
        let end = integrate_with(rod, &coeffs, y0, &mut |node: NodeAt, y| {
            if node.step > 0
                && nodes
                    .iter()
                    .any(|n| (n.0, n.1) == (node.section, node.step))
            {
                at_nodes.push(*y);
            }
            false
        });
        let g = tip.residual(&problem, loads, &end);
        let lu = DMatrix::from_fn(nx, nx, |i, j| g[i].eps[j]).lu();
        for (q, &c) in chunk.iter().enumerate() {
            let rhs = DVector::from_fn(nx, |i, _| -g[i].eps[nx + q]);
            let dx = solve_tangent(&lu, &rhs, || singular(sol))?;
            for (a, st) in at_nodes.iter().enumerate() {
                let p = pose_derivative(st, nx + q);
                let px: Vec<[f64; 6]> = (0..nx).map(|i| pose_derivative(st, i)).collect();
                for (_, r, row) in layout.coordinates().filter(|c| c.0 == a) {
                    dq[(row, c)] = p[r] + (0..nx).map(|i| px[i][r] * dx[i]).sum::<f64>();
                }
            }
        }
    }
    Ok(dq)
}

/// Columns of B: K dq/du for the pressures, the tensions and a mapped rod's factors sigma
/// (`dq`, [`Inputs`]); unit generalised forces at the tip node for the tip force and moment
/// (zero for a clamped tip: the clamp takes them; a pin takes the force), turned by the
/// tip's rotation `rot_l` for a follower tip load (its components are the tip frame's).
/// Column order: pressures, tip force, tip moment, tensions, sigma (three, for a rod with a
/// stiffness-mapped section).
#[allow(clippy::too_many_arguments)]
fn input_matrix(
    rod: &Rod,
    loads: &Loads,
    nodes: &[(usize, usize, f64)],
    layout: &Layout,
    stiffness: &DMatrix<f64>,
    dq: &DMatrix<f64>,
    tip: Tip,
    rot_l: &[[f64; 3]; 3],
) -> DMatrix<f64> {
    let Inputs { nc, nt, ns } = Inputs::of(rod);
    let nq = layout.size;
    let bp = stiffness * dq;
    let mut b = DMatrix::<f64>::zeros(nq, nc + 6 + nt + ns);
    for r in 0..nq {
        for c in 0..nc {
            b[(r, c)] = bp[(r, c)];
        }
        for t in 0..nt + ns {
            b[(r, nc + 6 + t)] = bp[(r, nc + t)];
        }
    }
    // The tip load's own columns: unit loads conjugate to the tip's coordinates (none on a
    // clamp, the moment on a pin), world components; a follower tip load's components are
    // the tip frame's, so its unit load is a column of R(L).
    let last = nodes.len() - 1;
    if !tip.clamped() {
        let follower = loads.tip_frame == Frame::Body;
        for (_, j, row) in layout.coordinates().filter(|c| c.0 == last) {
            let (i, k) = (j % 3, j - j % 3);
            for c in 0..3 {
                b[(row, nc + k + c)] = match (follower, i == c) {
                    (true, _) => rot_l[i][c],
                    (false, true) => 1.0,
                    (false, false) => 0.0,
                };
            }
        }
    }
    b
}
