//! Exact first derivatives of a static equilibrium that collocation solved (a long, soft
//! rod whose single shooting is ill-conditioned: docs/model.md, "Collocation"), with
//! respect to the inputs (pressures, dead tip loads, stiffness factors) and the design
//! parameters, by the implicit function theorem on the collocation equations
//! G(z, a) = 0 at the solution z:
//!
//!   dz/da = -G_z^-1 d_a G,
//!
//! with G_z the exact block-banded Newton matrix factored at z and d_a G one evaluation of
//! the residual with section models built from dual inputs or parameters
//! (`SectionModel<Jet<N>>`; the dead tip force and moment enter only the tip's balance
//! rows, -1/F_s and -1/M_s per unit). Outputs are read from the dual unknowns as the
//! solution's values are: node poses and the centreline's quadrature, and between nodes
//! the section's law over at most one step from the node
//! (`crate::sensitivity::advance_from_node`), so every derivative is that of the value
//! the solution reports. The shooting passes of `crate::jacobian` and
//! `crate::sensitivity` would leave such an equilibrium (they integrate from its base
//! unknowns). The linearisation builds on the same equations (`crate::linearise::
//! collocation`); the inverse still needs shooting passes and refuses these solutions
//! (`crate::jacobian::shooting_derivable`).

use super::{models_of, static_models, static_tip};
use crate::collocation::{rotation, Factorization, Grid, Problem, SectionModel, IM, IN, NF};
use crate::error::{Result, SoftrodError};
use crate::jacobian::{dual_coeffs_from, small_rotation, Input, PointJacobian, Probe};
use crate::jet::Jet;
use crate::ode::{Coeffs, Loads, State};
use crate::rod::Rod;
use crate::sensitivity::{
    advance_from_node, marker_position, seeded_coeffs, MarkerAt, Param, TipSensitivity,
};
use crate::statics::tangent::singular_jacobian;
use crate::statics::Solution;

/// Directions carried by one dual evaluation (more inputs or parameters: several).
const DIRS: usize = 4;
type Dual = Jet<DIRS>;

/// The collocation equations of a solution at its unknowns, with G_z factored.
pub(crate) struct Implicit<'a> {
    rod: &'a Rod,
    loads: &'a Loads,
    pub(crate) grid: Grid,
    models: Vec<SectionModel>,
    hist: Vec<[f64; NF]>,
    z: &'a [f64],
    fac: Factorization,
}

/// The dual unknowns of one set of directions, with the node positions they give.
pub(crate) struct DualSolution<const N: usize> {
    z: Vec<Jet<N>>,
    node_r: Vec<[Jet<N>; 3]>,
}

impl<'a> Implicit<'a> {
    /// The equations of `sol` (a collocation solution of `loads`) factored at its unknowns.
    pub(crate) fn of(rod: &'a Rod, loads: &'a Loads, sol: &'a Solution) -> Result<Self> {
        let z = match &sol.collocation {
            Some(c) => c.z.as_slice(),
            None => {
                return Err(SoftrodError::Internal(
                    "collocation derivatives of a shooting solution".into(),
                ))
            }
        };
        let grid = Grid::new(rod);
        let models = static_models(rod, &grid, loads, 1.0);
        let hist = vec![[0.0; NF]; 2 * grid.len() + 1];
        let fac = full_load(rod, loads, &grid, &models, &hist)
            .factorize(z)
            .ok_or_else(|| singular(sol))?;
        Ok(Implicit {
            rod,
            loads,
            grid,
            models,
            hist,
            z,
            fac,
        })
    }

    pub(crate) fn problem(&self) -> Problem<'_> {
        full_load(self.rod, self.loads, &self.grid, &self.models, &self.hist)
    }

    /// dz/da for the first `dirs` directions of `coeffs` (the sections' coefficients
    /// with those directions seeded), plus `terms` (residual row, direction, d row / d a)
    /// for inputs that enter the equations directly (a tip load the tip's balance, a
    /// point load the node recurrence).
    pub(crate) fn solve<const N: usize>(
        &self,
        coeffs: &[Coeffs<Jet<N>>],
        terms: &[(usize, usize, f64)],
        dirs: usize,
        sol: &Solution,
    ) -> Result<DualSolution<N>> {
        let p = self.problem();
        let models = models_of(self.rod, &self.grid, coeffs);
        let hist = vec![[Jet::<N>::from(0.0); NF]; self.hist.len()];
        let zc: Vec<Jet<N>> = self.z.iter().map(|&x| Jet::<N>::from(x)).collect();
        let mut r = p.residual_with(&models, &hist, &zc);
        for &(row, dir, d) in terms {
            r[row].eps[dir] += d;
        }
        let z = self
            .fac
            .implicit_step(self.z, &r, dirs)
            .ok_or_else(|| singular(sol))?;
        let (_, _, node_r) = p.fields_and_positions_with(&models, &hist, &z);
        Ok(DualSolution { z, node_r })
    }

    /// The state (pose, force, moment) at node j (0..=N) of the dual unknowns `d`: the
    /// left limit where a point load acts there.
    pub(crate) fn node_state<const N: usize>(
        &self,
        d: &DualSolution<N>,
        j: usize,
    ) -> State<Jet<N>> {
        let y = self.problem().node_with(&d.z, j);
        State {
            r: d.node_r[j],
            rot: rotation(&y[..4]),
            n: [y[IN], y[IN + 1], y[IN + 2]],
            m: [y[IM], y[IM + 1], y[IM + 2]],
            aux: [Jet::<N>::from(1.0); 2],
        }
    }

    /// The state at `mk`, read as the solution's value is.
    fn state_at<const N: usize>(
        &self,
        d: &DualSolution<N>,
        coeffs: &[Coeffs<Jet<N>>],
        mk: &MarkerAt,
    ) -> State<Jet<N>> {
        advance_from_node(self.rod, coeffs, self.node_state(d, mk.node), mk)
    }
}

/// The static problem at full load (`super::solve_static`'s at load factor 1).
fn full_load<'p>(
    rod: &'p Rod,
    loads: &Loads,
    grid: &'p Grid,
    models: &'p [SectionModel],
    hist: &'p [[f64; NF]],
) -> Problem<'p> {
    Problem::new(rod, grid, models, 0.0, hist, static_tip(rod, loads, 1.0))
}

fn singular(sol: &Solution) -> SoftrodError {
    singular_jacobian(
        sol.iterations,
        sol.residual,
        "the collocation Jacobian",
        "derivatives",
    )
}

/// The tip as a marker (the last node).
fn tip_marker(rod: &Rod) -> MarkerAt {
    Probe::tip(rod).on_centreline(rod)
}

/// [`crate::jacobian::point_jacobian`] of a collocation solution.
pub(crate) fn point_jacobian(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    inputs: &[Input],
    probe: &Probe,
) -> Result<PointJacobian> {
    let imp = Implicit::of(rod, loads, sol)?;
    let mk = probe.on_centreline(rod);
    let (fs, ms, rows) = {
        let p = imp.problem();
        (p.fs, p.ms, p.tip_rows())
    };
    let mut out = PointJacobian {
        position: [0.0; 3],
        rotation: [[0.0; 3]; 3],
        d_position: Vec::with_capacity(inputs.len()),
        d_rotation: Vec::with_capacity(inputs.len()),
    };
    // One evaluation even without inputs: it gives the point's value.
    let chunks: Vec<&[Input]> = if inputs.is_empty() {
        vec![&[]]
    } else {
        inputs.chunks(DIRS).collect()
    };
    for chunk in chunks {
        let coeffs = dual_coeffs_from::<DIRS>(rod, loads, chunk, 0);
        let tip: Vec<(usize, usize, f64)> = chunk
            .iter()
            .enumerate()
            .filter_map(|(q, a)| match a {
                // Tip rows: (n(L) - ... - F) / F_s, then (m(L) - ... - M) / M_s.
                Input::TipForce(j) => Some((rows + *j, q, -1.0 / fs)),
                Input::TipMoment(j) => Some((rows + 3 + *j, q, -1.0 / ms)),
                _ => None,
            })
            .collect();
        let d = imp.solve(&coeffs, &tip, chunk.len(), sol)?;
        let y = imp.state_at(&d, &coeffs, &mk);
        out.position = y.r.map(|v| v.re);
        out.rotation = y.rot.map(|row| row.map(|v| v.re));
        for q in 0..chunk.len() {
            out.d_position.push(y.r.map(|v| v.eps[q]));
            let d_rot = y.rot.map(|row| row.map(|v| v.eps[q]));
            out.d_rotation.push(small_rotation(&out.rotation, &d_rot));
        }
    }
    Ok(out)
}

/// [`crate::sensitivity::pose_sensitivity`] of a collocation solution: the tip pose's and
/// the markers' derivatives with respect to the (validated) parameters.
pub(crate) fn pose_sensitivity(
    rod: &Rod,
    loads: &Loads,
    sol: &Solution,
    params: &[Param],
    markers: &[MarkerAt],
) -> Result<TipSensitivity> {
    let imp = Implicit::of(rod, loads, sol)?;
    let tip = tip_marker(rod);
    let mut out = TipSensitivity {
        position: Vec::with_capacity(params.len()),
        rotation: Vec::with_capacity(params.len()),
        markers: Vec::with_capacity(params.len()),
        reaction_force: vec![],
        reaction_moment: vec![],
    };
    for chunk in params.chunks(DIRS) {
        let (coeffs, _) = seeded_coeffs::<DIRS>(rod, loads, chunk);
        let d = imp.solve(&coeffs, &[], chunk.len(), sol)?;
        let y = imp.state_at(&d, &coeffs, &tip);
        let marks: Vec<[Dual; 3]> = markers
            .iter()
            .map(|mk| marker_position(&imp.state_at(&d, &coeffs, mk), &mk.offset))
            .collect();
        for q in 0..chunk.len() {
            out.position.push(y.r.map(|v| v.eps[q]));
            out.rotation.push(y.rot.map(|row| row.map(|v| v.eps[q])));
            out.markers
                .push(marks.iter().map(|m| m.map(|v| v.eps[q])).collect());
        }
    }
    Ok(out)
}
