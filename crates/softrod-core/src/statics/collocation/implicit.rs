//! The implicit function theorem on a static equilibrium that collocation solved (a long,
//! soft rod whose single shooting is ill-conditioned: docs/model.md, "Collocation"): the
//! collocation equations G(z, a) = 0 at the solution z give
//!
//!   dz/da = -G_z^-1 d_a G,
//!
//! with G_z the exact block-banded Newton matrix factored at z and d_a G one evaluation of
//! the residual with section models built from dual inputs or parameters
//! (`SectionModel<Jet<N>>`), plus terms for inputs that enter the equations directly (a
//! tip load the tip's balance rows, -1/F_s and -1/M_s per unit; a point load the node
//! recurrence). The dual unknowns give the node states (pose, force, moment) with their
//! derivatives, from which the callers read their outputs as the solution's values are
//! read (`crate::jacobian::collocation`, `crate::sensitivity::collocation`,
//! `crate::linearise::collocation`). Shooting passes from the base unknowns would leave
//! such an equilibrium.

use super::{models_of, static_models, static_tip};
use crate::collocation::{rotation, Factorization, Grid, Problem, SectionModel, IM, IN, NF};
use crate::error::{Result, SoftrodError};
use crate::jet::Jet;
use crate::ode::{Coeffs, Loads, State};
use crate::rod::Rod;
use crate::statics::tangent::singular_jacobian;
use crate::statics::Solution;

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
