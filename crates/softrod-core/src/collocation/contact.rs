//! Contact with rigid obstacles in the collocation equations (docs/contact.md, "Dynamics";
//! docs/model.md, "Collocation").
//!
//! The penalty law (`crate::contact`) is a line load that depends on the centreline r,
//! which the collocation otherwise recovers after the solve. With obstacles the node
//! positions r_1 .. r_N join the unknowns (appended after the usual ones, so the layout of
//! everything else is unchanged) with the node recurrence of the same quadrature,
//!   r_{j+1} = r_j + h sum_k b_k R_k v_k,
//! and the stage positions are explicit in the interval's unknowns,
//!   r_i = r_j + h sum_k a_ik R_k v_k,
//! so each interval's equations depend on its start node (Y_j, r_j), its stages and its end
//! node only. Their Jacobian is exact: one evaluation in `Jet<51>` over (Y_j, r_j, Y_1,
//! Y_2) per interval. The stage loads couple the two stages (through r_i) and the node
//! positions, so the condensed 16-wide node recurrence of the contact-free solver does not
//! apply; the whole system (51 unknowns per interval) is one banded matrix of 63 sub- and
//! 56 super-diagonals, still O(N). Rods without obstacles never come here and cost what
//! they did.
//!
//! A pinned or clamped tip (`Problem::end`, docs/model.md "End constraints") takes the same
//! path, with or without obstacles: its equation r(L) = r_c needs the tip's position as an
//! unknown; it replaces the tip's force balance (and, clamped, the orientation error
//! replaces the moment balance), the same 6 rows in the same place of the band.

use super::{
    mat_vec, rotation, Factorization, Problem, SectionModel, GAUSS_A, GAUSS_B, IM, IN, IQ, IV, IW,
    NF, NY,
};
use crate::banded::BandedLu;
use crate::contact::{total_section_load, Obstacle, SectionLoad};
use crate::jet::{Coeff, Jet, RodScalar, StateScalar};
use crate::rod::Rod;
use crate::statics::constraint::{orientation_error, tmatmul};
use std::sync::Arc;

/// Unknowns (and equations) per interval with contact: two stages, the end node, its
/// position.
const PER: usize = 51;
/// Sub- and super-diagonals of the banded system (module docs).
const KL: usize = 63;
const KU: usize = 56;

/// The obstacles of a collocation problem and the rod's surface radius where it meets
/// them.
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    pub obstacles: Arc<[Obstacle]>,
    /// Surface radius at each stage point (2 per interval), m.
    pub stage_radius: Vec<f64>,
    /// Surface radius of the rounded end (the tip's), m.
    pub tip_radius: f64,
}

impl Contact {
    /// The contact data of a rod on `grid`; None without obstacles.
    pub fn of(rod: &Rod, grid: &super::Grid) -> Option<Self> {
        let obstacles = rod.obstacles.clone()?;
        let stage_radius = grid
            .intervals
            .iter()
            .flat_map(|iv| {
                let sec = &rod.sections[iv.section];
                [0, 1].map(|i| sec.surface_radius(iv.stage_local(i)))
            })
            .collect();
        let last = rod.sections.last()?;
        Some(Contact {
            obstacles,
            stage_radius,
            tip_radius: last.surface_radius(last.length),
        })
    }

    /// The load per unit length at a cross-section of state `y` (its velocities and
    /// rotation) with centreline at `r` and surface radius `rho`.
    pub fn load<D: StateScalar<f64>>(&self, y: &[D; NY], r: &[D; 3], rho: f64) -> SectionLoad<D> {
        let rot = rotation(&y[IQ..IQ + 4]);
        let vel = mat_vec(&rot, &[y[IV], y[IV + 1], y[IV + 2]]);
        let omega = mat_vec(&rot, &[y[IW], y[IW + 1], y[IW + 2]]);
        total_section_load(&self.obstacles, r, &vel, &omega, rho)
    }

    /// The load on the rounded end at the tip state `y`, position `r` (N, N m): the
    /// line load of the tip's cross-section over the cap's length rho, as in the statics
    /// (`crate::statics::contact::end_force`).
    pub fn end_load<D: StateScalar<f64>>(&self, y: &[D; NY], r: &[D; 3]) -> SectionLoad<D> {
        let l = self.load(y, r, self.tip_radius);
        let rho = self.tip_radius;
        SectionLoad {
            force: l.force.map(|x| x * rho),
            moment: l.moment.map(|x| x * rho),
            friction: l.friction.map(|x| x * rho),
        }
    }
}

/// Row of the banded system of scaled residual entry `i` (layout of
/// [`Problem::residual`]: 48 per interval, the 6 tip rows, then 3 position rows per
/// interval).
pub(super) fn residual_to_full(n_int: usize, i: usize) -> usize {
    let tip = 48 * n_int;
    if i < tip {
        PER * (i / 48) + i % 48
    } else if i < tip + 6 {
        PER * n_int + (i - tip)
    } else {
        let k = i - tip - 6;
        PER * (k / 3) + 48 + k % 3
    }
}

/// Column of the banded system of scaled unknown `i` (6 base unknowns, 48 per interval,
/// then 3 positions per interval).
pub(super) fn unknown_to_full(n_int: usize, i: usize) -> usize {
    let pos = 6 + 48 * n_int;
    if i < pos {
        if i < 6 {
            i
        } else {
            6 + PER * ((i - 6) / 48) + (i - 6) % 48
        }
    } else {
        let k = i - pos;
        6 + PER * (k / 3) + 48 + k % 3
    }
}

/// The inverse of [`residual_to_full`].
pub(super) fn full_to_residual(n_int: usize, row: usize) -> usize {
    if row >= PER * n_int {
        48 * n_int + (row - PER * n_int)
    } else {
        let (j, k) = (row / PER, row % PER);
        if k < 48 {
            48 * j + k
        } else {
            48 * n_int + 6 + 3 * j + (k - 48)
        }
    }
}

/// The inverse of [`unknown_to_full`].
pub(super) fn full_to_unknown(n_int: usize, col: usize) -> usize {
    if col < 6 {
        return col;
    }
    let (j, k) = ((col - 6) / PER, (col - 6) % PER);
    if k < 48 {
        6 + 48 * j + k
    } else {
        6 + 48 * n_int + 3 * j + (k - 48)
    }
}

impl Problem<'_> {
    /// Index in the unknowns of node j's position (j >= 1).
    fn position_index(&self, j: usize) -> usize {
        self.grid.unknowns() + 3 * (j - 1)
    }

    /// Physical position of node j from scaled unknowns.
    pub(super) fn position(&self, z: &[f64], j: usize) -> [f64; 3] {
        self.position_with(z, j)
    }

    /// [`Problem::position`] of unknowns in any scalar.
    fn position_with<D: RodScalar>(&self, z: &[D], j: usize) -> [D; 3] {
        if j == 0 {
            return self.rod.base_position.map(D::from);
        }
        let o = self.position_index(j);
        std::array::from_fn(|k| z[o + k] * self.rod.length)
    }

    /// Interval j's scaled equations with contact (32 stage rows, 16 node rows, 3 position
    /// rows) from its start node (Y_j, r_j), stages and end node (Y_{j+1}, r_{j+1}), all
    /// physical, and the stage fields, under section `models` and histories `hist` (the
    /// problem's own, or dual ones for parameter derivatives: `Problem::residual_with`).
    #[allow(clippy::too_many_arguments)]
    fn contact_interval<C: Coeff, D: StateScalar<C>>(
        &self,
        models: &[SectionModel<C>],
        hist: &[[C; NF]],
        c: Option<&Contact>,
        j: usize,
        yj: &[D; NY],
        rj: &[D; 3],
        ys: [&[D; NY]; 2],
        yn: &[D; NY],
        rn: &[D; 3],
    ) -> ([D; PER], [[D; NF]; 2]) {
        let iv = &self.grid.intervals[j];
        let hh = iv.h;
        let inv: [f64; NY] = self.scale.map(|s| 1.0 / s);
        let mut f = [[D::from(0.0); NY]; 2];
        let mut fl = [[D::from(0.0); NF]; 2];
        let mut dr = [[D::from(0.0); 3]; 2];
        for i in 0..2 {
            let (fi, fli) = super::rhs(
                ys[i],
                &models[iv.model[i]],
                &hist[2 * j + i],
                self.c0,
                iv.stage_local(i),
            );
            let rot = rotation(&ys[i][IQ..IQ + 4]);
            dr[i] = mat_vec(&rot, &[fli[0], fli[1], fli[2]]);
            f[i] = fi;
            fl[i] = fli;
        }
        for i in 0..2 {
            let Some(c) = c else { break };
            // The stage position by the stage quadrature, and the contact load there as a
            // line force and moment: n' = ... - f_c, m' = ... - l_c.
            let ri: [D; 3] = std::array::from_fn(|k| {
                rj[k] + (dr[0][k] * GAUSS_A[i][0] + dr[1][k] * GAUSS_A[i][1]) * hh
            });
            let load = c.load(ys[i], &ri, c.stage_radius[2 * j + i]);
            for k in 0..3 {
                f[i][IN + k] -= load.force[k];
                f[i][IM + k] -= load.moment[k];
            }
        }
        let mut out = [D::from(0.0); PER];
        for k in 0..NY {
            let comb = |a: f64, b: f64| (f[0][k] * a + f[1][k] * b) * hh;
            out[k] = (ys[0][k] - yj[k] - comb(GAUSS_A[0][0], GAUSS_A[0][1])) * inv[k];
            out[16 + k] = (ys[1][k] - yj[k] - comb(GAUSS_A[1][0], GAUSS_A[1][1])) * inv[k];
            out[32 + k] = (yn[k] - yj[k] - comb(GAUSS_B[0], GAUSS_B[1])) * inv[k];
        }
        let il = 1.0 / self.rod.length;
        for k in 0..3 {
            out[48 + k] =
                (rn[k] - rj[k] - (dr[0][k] * GAUSS_B[0] + dr[1][k] * GAUSS_B[1]) * hh) * il;
        }
        (out, fl)
    }

    /// The free tip's scaled wrench balance with the rounded end's contact load.
    pub(super) fn free_tip<D: StateScalar<f64>>(
        &self,
        c: Option<&Contact>,
        y: &[D; NY],
        r: &[D; 3],
    ) -> [D; 6] {
        self.free_tip_with(c, y, r, self.hist.last().expect("tip slot"))
    }

    /// Exact derivatives of the free tip's scaled balance ([`Problem::tip_reaction`]'s,
    /// the rounded end's contact included) with respect to the tip node's 16 scaled
    /// unknowns and to its 3 scaled position unknowns (zero where the positions are not
    /// unknowns: then no contact term reads them).
    pub fn reaction_jacobian(
        &self,
        z: &[f64],
    ) -> (nalgebra::SMatrix<f64, 6, NY>, nalgebra::SMatrix<f64, 6, 3>) {
        const NJ: usize = NY + 3;
        let n = self.grid.len();
        let yn = self.node(z, n);
        // Seeded with the scales: derivatives with respect to the scaled unknowns.
        let seed = |re: f64, i: usize, scale: f64| {
            let mut eps = [0.0; NJ];
            eps[i] = scale;
            Jet { re, eps }
        };
        let y: [Jet<NJ>; NY] = std::array::from_fn(|k| seed(yn[k], k, self.scale[k]));
        let rn = if self.has_positions() {
            self.position(z, n)
        } else {
            [0.0; 3]
        };
        let r: [Jet<NJ>; 3] = std::array::from_fn(|k| seed(rn[k], NY + k, self.rod.length));
        let t = self.free_tip(self.contact.as_ref(), &y, &r);
        (
            nalgebra::SMatrix::from_fn(|i, c| t[i].eps[c]),
            nalgebra::SMatrix::from_fn(|i, c| t[i].eps[NY + c]),
        )
    }

    /// [`Problem::tip_reaction`] of scaled unknowns `z` and histories `hist` in any scalar
    /// (the parameter sensitivities of a system of rods, `dynamics::system`: the tip
    /// slot's history carries its derivatives).
    pub fn tip_reaction_with<C: Coeff, D: StateScalar<C>>(
        &self,
        hist: &[[C; NF]],
        z: &[D],
    ) -> ([D; 3], [D; 3]) {
        let zero = [D::from(0.0); 3];
        let Some(end) = self.end else {
            return (zero, zero);
        };
        let n = self.grid.len();
        let y = self.node_with(z, n);
        let r = self.position_with(z, n);
        let th = hist.last().expect("tip slot");
        let t = self.free_tip_with(self.contact.as_ref(), &y, &r, th);
        let force = std::array::from_fn(|k| t[k] * self.fs);
        let moment = if end.rotation.is_some() {
            std::array::from_fn(|k| t[3 + k] * self.ms)
        } else {
            zero
        };
        (force, moment)
    }

    /// Offset in the unknowns of the tip's 3 scaled position unknowns (a problem whose
    /// node positions are unknowns, [`Problem::has_positions`]).
    pub fn tip_position_offset(&self) -> usize {
        self.position_index(self.grid.len())
    }

    /// [`Problem::free_tip`] with the tip node's history terms `th` in any scalar.
    fn free_tip_with<C: Coeff, D: StateScalar<C>>(
        &self,
        c: Option<&Contact>,
        y: &[D; NY],
        r: &[D; 3],
        th: &[C; NF],
    ) -> [D; 6] {
        let mut t = self.tip_residual_with(y, th);
        if let Some(c) = c {
            let e = c.end_load(y, r);
            for k in 0..3 {
                t[k] -= e.force[k] * (1.0 / self.fs);
                t[3 + k] -= e.moment[k] * (1.0 / self.ms);
            }
        }
        t
    }

    /// The tip's 6 scaled equations: the free tip's balance, or for a constrained tip
    /// (`Problem::end`) the position (r(L) - r_c)/L in place of the force balance and, when
    /// clamped, the orientation error e(R_c^T R(L)) in place of the moment balance.
    fn contact_tip<C: Coeff, D: StateScalar<C>>(
        &self,
        c: Option<&Contact>,
        y: &[D; NY],
        r: &[D; 3],
        th: &[C; NF],
    ) -> [D; 6] {
        let mut t = self.free_tip_with(c, y, r, th);
        if let Some(end) = &self.end {
            let il = 1.0 / self.rod.length;
            for k in 0..3 {
                t[k] = (r[k] - end.position[k]) * il;
            }
            if let Some(rc) = &end.rotation {
                let rot = rotation(&y[IQ..IQ + 4]);
                let e = orientation_error(&tmatmul(&rc.map(|row| row.map(D::from)), &rot));
                t[3..].copy_from_slice(&e);
            }
        }
        t
    }

    /// [`Problem::residual`] with contact.
    pub(super) fn contact_residual(
        &self,
        c: Option<&Contact>,
        z: &[f64],
        out: &mut [f64],
        fields: Option<&mut [[f64; NF]]>,
    ) {
        self.contact_residual_with(self.models, self.hist, c, z, out, fields);
    }

    /// [`Problem::contact_residual`] under section `models` and histories `hist`, in any
    /// scalar (`Problem::residual_with`: the parameter derivatives of a run with contact
    /// or a held tip).
    pub(super) fn contact_residual_with<C: Coeff, D: StateScalar<C>>(
        &self,
        models: &[SectionModel<C>],
        hist: &[[C; NF]],
        c: Option<&Contact>,
        z: &[D],
        out: &mut [D],
        mut fields: Option<&mut [[D; NF]]>,
    ) {
        let n_int = self.grid.len();
        let mut yj = self.node_with(z, 0);
        let mut rj = self.position_with(z, 0);
        for j in 0..n_int {
            let (y1, y2) = (self.stage_with(z, j, 0), self.stage_with(z, j, 1));
            let yn = self.node_with(z, j + 1);
            let rn = self.position_with(z, j + 1);
            let (r, fl) = self.contact_interval(models, hist, c, j, &yj, &rj, [&y1, &y2], &yn, &rn);
            out[48 * j..48 * j + 48].copy_from_slice(&r[..48]);
            let o = 48 * n_int + 6 + 3 * j;
            out[o..o + 3].copy_from_slice(&r[48..]);
            if let Some(f) = fields.as_mut() {
                f[2 * j] = fl[0];
                f[2 * j + 1] = fl[1];
            }
            yj = yn;
            rj = rn;
        }
        let t = self.contact_tip(c, &yj, &rj, hist.last().expect("tip slot"));
        out[48 * n_int..48 * n_int + 6].copy_from_slice(&t);
    }

    /// The exact Jacobian of the scaled residual with contact with respect to the scaled
    /// unknowns, entry by entry as (row, column, value) of the banded system's order
    /// ([`residual_to_full`], [`unknown_to_full`]); every entry is given once.
    pub(super) fn contact_jacobian(
        &self,
        c: Option<&Contact>,
        z: &[f64],
        mut put: impl FnMut(usize, usize, f64),
    ) {
        let n_int = self.grid.len();
        let l = self.rod.length;
        // A scaled unknown as a jet variable (slot `slot` of `M`), or a constant.
        fn var<const M: usize>(x: f64, scale: f64, slot: Option<usize>) -> Jet<M> {
            let mut e = [0.0; M];
            if let Some(s) = slot {
                e[s] = scale;
            }
            Jet { re: x, eps: e }
        }
        for j in 0..n_int {
            // Local variables: Y_j (0..16), r_j (16..19), Y_1 (19..35), Y_2 (35..51).
            let y0 = self.node(z, j);
            let r0 = self.position(z, j);
            let yj: [Jet<PER>; NY] = std::array::from_fn(|k| {
                let free = j > 0 || (IN..IN + 6).contains(&k);
                var(y0[k], self.scale[k], free.then_some(k))
            });
            let rj: [Jet<PER>; 3] =
                std::array::from_fn(|k| var(r0[k], l, (j > 0).then_some(16 + k)));
            let st = |i: usize| -> [Jet<PER>; NY] {
                let y = self.stage(z, j, i);
                std::array::from_fn(|k| var(y[k], self.scale[k], Some(19 + 16 * i + k)))
            };
            let (y1, y2) = (st(0), st(1));
            let yn0 = self.node(z, j + 1);
            let rn0 = self.position(z, j + 1);
            let yn: [Jet<PER>; NY] = std::array::from_fn(|k| var(yn0[k], 1.0, None));
            let rn: [Jet<PER>; 3] = std::array::from_fn(|k| var(rn0[k], 1.0, None));
            let (res, _) =
                self.contact_interval(self.models, self.hist, c, j, &yj, &rj, [&y1, &y2], &yn, &rn);
            // The unknown of local variable v; None for the base values the problem holds
            // fixed (interval 0's node outside IN..IN + 6 and its position: not seeded).
            let col_of = |v: usize| -> Option<usize> {
                match v {
                    0..=15 if j == 0 => (IN..IN + 6).contains(&v).then(|| v - IN),
                    16..=18 if j == 0 => None,
                    0..=15 => Some(6 + PER * (j - 1) + 32 + v),
                    16..=18 => Some(6 + PER * (j - 1) + 48 + (v - 16)),
                    _ => Some(6 + PER * j + (v - 19)),
                }
            };
            for (row, r) in res.iter().enumerate() {
                for (v, d) in r.eps.iter().enumerate() {
                    put_entry(&mut put, PER * j + row, col_of(v), *d);
                }
            }
            // The end node and its position enter their rows with unit weight.
            for k in 0..19 {
                put(PER * j + 32 + k, 6 + PER * j + 32 + k, 1.0);
            }
        }
        // The tip rows: over Y_N (0..16) and r_N (16..19).
        let yn0 = self.node(z, n_int);
        let rn0 = self.position(z, n_int);
        let y: [Jet<19>; NY] = std::array::from_fn(|k| var(yn0[k], self.scale[k], Some(k)));
        let r: [Jet<19>; 3] = std::array::from_fn(|k| var(rn0[k], l, Some(16 + k)));
        let t = self.contact_tip(c, &y, &r, self.hist.last().expect("tip slot"));
        let node = 6 + PER * (n_int - 1) + 32;
        for (row, x) in t.iter().enumerate() {
            for (v, d) in x.eps.iter().enumerate() {
                put_entry(&mut put, PER * n_int + row, Some(node + v), *d);
            }
        }
    }

    /// [`Problem::factorize`] with contact: the whole banded system.
    pub(super) fn contact_factorize(&self, z: &[f64]) -> Option<Factorization> {
        let n = self.unknowns();
        let mut band = BandedLu::zeros(n, KL, KU);
        let mut broken = false;
        self.contact_jacobian(self.contact.as_ref(), z, |i, j, v| {
            broken |= v.is_nan();
            band.set(i, j, v)
        });
        if broken || !band.factor() {
            return None;
        }
        Some(Factorization {
            blocks: Vec::new(),
            band,
            contact: true,
            at: z.to_vec(),
        })
    }
}

/// One entry of the contact Jacobian: `d` at (`row`, `col`) when it is a finite derivative
/// with respect to an unknown. A derivative that is not finite (an overflowing load, e.g.
/// a tendon of tens of kN pressing a section through an obstacle), or a non-zero one with
/// respect to a value held fixed (only a non-finite seed can make one), breaks the Jacobian:
/// a NaN on the row's diagonal marks it, the factorization refuses it, and Newton reports the
/// step as not converged instead of writing an entry outside the band or into the wrong
/// column.
#[inline]
fn put_entry(put: &mut impl FnMut(usize, usize, f64), row: usize, col: Option<usize>, d: f64) {
    if d == 0.0 {
        return;
    }
    match col {
        Some(c) if d.is_finite() => put(row, c, d),
        _ => put(row, row, f64::NAN),
    }
}
