"""Baseline and independent reference: softrod's static model solved with scipy's solve_bvp.

This re-implements, in numpy only, the static Cosserat rod of docs/model.md exactly
as softrod states it (crates/softrod-core/src/ode.rs), without calling the Rust solver:

    v = K_se^-1 (R^T n + P e3) + e3,           P = sum_k p_k A_k,
    u = K_bt^-1 (R^T m + sum_k p_k A_k (y_k, -x_k, 0)),
    r' = R v,   R' = R u^,   n' = -f,   m' = -r' x n - l,

with f = rho A g (line mass times the design's gravity vector) plus user line loads, rigid
sections carried straight through (v = e3, u = 0), the base clamped at the mounting pose and the
tip loaded by the dead force and moment plus the tip body's weight acting at its centre of mass:

    n(L) = F_tip + m_t g,   m(L) = M_tip + (R(L) c) x (m_t g).

Only the section data softrod compiles from the geometry is shared (``design.sections()``:
K_se, K_bt, line mass, chamber areas and centroids); the balance laws, the constitutive law and
the boundary conditions are written out again here.

The coefficients jump at section junctions, which a collocation method cannot see inside a
mesh interval. So every section gets its own copy of the 18-component state on a normalised
coordinate t in [0, 1] (s = s_start + t L_i), and continuity of (r, R, n, m) across junctions
becomes boundary conditions: one smooth BVP of 18 x (number of sections) components.

Cold start from the straight rod (r = r0 + s d3, R = R0) with the internal force and moment of
the straight rod under its weight and tip loads, the same guess softrod's shooting starts from.

Run as a script for a quick comparison with softrod:
    python benchmarks/baseline_bvp.py
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_bvp

# Levi-Civita symbol: EPS[i, j, k] = e_i . (e_j x e_k)
EPS = np.zeros((3, 3, 3))
EPS[0, 1, 2] = EPS[1, 2, 0] = EPS[2, 0, 1] = 1.0
EPS[0, 2, 1] = EPS[2, 1, 0] = EPS[1, 0, 2] = -1.0

# Default numerics (reference use): tol is solve_bvp's relative collocation residual; with the
# state scaled as below, tol = 1e-6 on 20 initial nodes per section (60 along the rod) puts the
# tip within ~5e-9 L of the converged model for the bundled SPA designs (measured by
# ``python benchmarks/baseline_bvp.py``), far inside the 1e-6 L target. The benchmark picks its
# own (larger) tol by the same 1e-6 L accuracy criterion it applies to softrod.
DEFAULT_NODES = 20
DEFAULT_TOL = 1e-6


@dataclass(frozen=True)
class _Problem:
    """Per-solve coefficients, one row per section, and the scales of the state."""

    lengths: np.ndarray  # (ns,) section lengths, m
    s_start: np.ndarray  # (ns,)
    c_se: np.ndarray  # (ns, 3) diagonal of K_se^-1 (0 for rigid)
    c_bt: np.ndarray  # (ns, 3, 3) K_bt^-1 (0 for rigid)
    v_shift: np.ndarray  # (ns, 3) e3 + K_se^-1 P e3
    u_shift: np.ndarray  # (ns, 3) K_bt^-1 sum p_k A_k (y_k, -x_k, 0)
    f: np.ndarray  # (ns, 3) line force, world, N/m
    lm: np.ndarray  # (ns, 3) line moment l, world, N m/m
    r0: np.ndarray  # (3,)
    rot0: np.ndarray  # (3, 3) base rotation, columns d1 d2 d3
    f_tip: np.ndarray  # (3,) dead tip force plus tip-body weight, world
    m_tip: np.ndarray  # (3,) dead tip moment
    w_tip: np.ndarray  # (3,) tip-body weight
    com: np.ndarray  # (3,) tip centre-of-mass offset in the tip frame
    scale: np.ndarray  # (18,) unit of each state component (r: L, R: 1, n: F0, m: F0 L)

    @property
    def ns(self) -> int:
        return len(self.lengths)


def build_problem(design, pressures, tip_force=None, tip_moment=None) -> _Problem:
    """Coefficients of the static BVP of ``design`` under ``pressures`` (Pa, one per channel)."""
    spec = design.spec
    secs = design.sections()
    p = np.asarray(pressures, dtype=float).reshape(-1)
    if p.size != design.n_channels:
        raise ValueError(f"need {design.n_channels} pressures, got {p.size}")
    g = np.asarray(spec["mounting"]["gravity"], dtype=float)
    ns = len(secs)
    lengths = np.array([s["length"] for s in secs])
    s_start = np.array([s["s_start"] for s in secs])
    c_se = np.zeros((ns, 3))
    c_bt = np.zeros((ns, 3, 3))
    v_shift = np.tile([0.0, 0.0, 1.0], (ns, 1))
    u_shift = np.zeros((ns, 3))
    f = np.zeros((ns, 3))
    lm = np.zeros((ns, 3))
    for i, s in enumerate(secs):
        f[i] = s["line_mass"] * g
        if s["rigid"]:
            continue
        k_se = np.asarray(s["k_se"], dtype=float)
        k_bt = np.asarray(s["k_bt"], dtype=float)
        c_se[i] = 1.0 / k_se
        c_bt[i] = np.linalg.inv(k_bt)
        force = 0.0
        mp = np.zeros(3)
        for area, x, y, channel in s["chambers"]:
            pa = p[channel] * area
            force += pa
            mp += pa * np.array([y, -x, 0.0])
        v_shift[i, 2] += c_se[i, 2] * force
        u_shift[i] = c_bt[i] @ mp
    for load in spec.get("loads", []):
        f[load["section"]] += np.asarray(load["force_per_length"], dtype=float)
        lm[load["section"]] += np.asarray(load["moment_per_length"], dtype=float)
    tip = spec["tip"]
    w_tip = tip["mass"] * g
    ft = np.asarray(tip["force"] if tip_force is None else tip_force, dtype=float)
    mt = np.asarray(tip["moment"] if tip_moment is None else tip_moment, dtype=float)
    length = float(lengths.sum())
    ei = [min(s["k_bt"][0][0], s["k_bt"][1][1]) for s in secs if not s["rigid"]]
    f0 = min(ei) / length**2 if ei else 1.0
    scale = np.concatenate(
        [np.full(3, length), np.ones(9), np.full(3, f0), np.full(3, f0 * length)]
    )
    return _Problem(
        lengths=lengths,
        s_start=s_start,
        c_se=c_se,
        c_bt=c_bt,
        v_shift=v_shift,
        u_shift=u_shift,
        f=f,
        lm=lm,
        r0=np.asarray(spec["mounting"]["base_position"], dtype=float),
        rot0=np.asarray(spec["mounting"]["base_rotation"], dtype=float),
        f_tip=ft + w_tip,
        m_tip=mt,
        w_tip=w_tip,
        com=np.asarray(tip["com_offset"], dtype=float),
        scale=scale,
    )


def _unpack(pb: _Problem, y: np.ndarray):
    """Scaled state (18 ns, m) -> physical r, R, n, m with shapes (ns, 3, m) / (ns, 3, 3, m)."""
    m_nodes = y.shape[-1]
    z = y.reshape(pb.ns, 18, m_nodes) * pb.scale[None, :, None]
    return z[:, 0:3], z[:, 3:12].reshape(pb.ns, 3, 3, m_nodes), z[:, 12:15], z[:, 15:18]


def _strains(pb: _Problem, rot, n, mom):
    nb = np.einsum("skjm,skm->sjm", rot, n)  # R^T n
    mb = np.einsum("skjm,skm->sjm", rot, mom)  # R^T m
    v = pb.c_se[:, :, None] * nb + pb.v_shift[:, :, None]
    u = np.einsum("sij,sjm->sim", pb.c_bt, mb) + pb.u_shift[:, :, None]
    return v, u


def rhs(pb: _Problem, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """dy/dt of the scaled, per-section state at the nodes t (vectorised over nodes)."""
    _, rot, n, mom = _unpack(pb, y)
    v, u = _strains(pb, rot, n, mom)
    dr = np.einsum("sijm,sjm->sim", rot, v)
    # R u^, column j: sum_k R_ik eps_{k l j} u_l
    drot = np.einsum("sikm,klj,slm->sijm", rot, EPS, u)
    dn = np.broadcast_to(-pb.f[:, :, None], n.shape)
    dm = -np.cross(dr, n, axis=1) - pb.lm[:, :, None]
    m_nodes = y.shape[-1]
    out = np.concatenate([dr, drot.reshape(pb.ns, 9, m_nodes), dn, dm], axis=1)
    out *= (pb.lengths[:, None, None]) / pb.scale[None, :, None]
    return out.reshape(18 * pb.ns, m_nodes)


def rhs_jac(pb: _Problem, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Exact d(rhs)/dy, shape (18 ns, 18 ns, m), block diagonal over sections."""
    _, rot, n, mom = _unpack(pb, y)
    v, u = _strains(pb, rot, n, mom)
    ns, m_nodes = pb.ns, y.shape[-1]
    eye = np.eye(3)
    dr = np.einsum("sijm,sjm->sim", rot, v)
    j = np.zeros((ns, 18, 18, m_nodes))
    # d r'_i / d R_kl = delta_ik v_l + R_il c_se_l n_k
    d_dr_drot = np.einsum("ik,slm->siklm", eye, v) + np.einsum(
        "silm,sl,skm->siklm", rot, pb.c_se, n
    )
    a = np.einsum("sijm,sj,skjm->sikm", rot, pb.c_se, rot)  # d r'/d n = R C_se R^T
    j[:, 0:3, 3:12] = d_dr_drot.reshape(ns, 3, 9, m_nodes)
    j[:, 0:3, 12:15] = a
    # R'_ij = sum_kl R_ik eps_klj u_l;  du_l/dR_ab = c_bt_lb m_a;  du_l/dm_a = (C_bt R^T)_la
    ru = np.einsum("sikm,klj->sijlm", rot, EPS)  # d R'_ij / d u_l
    uhat = np.einsum("blj,slm->sbjm", EPS, u)  # u^_bj
    d_drot_drot = np.einsum("ia,sbjm->sijabm", eye, uhat) + np.einsum(
        "sijlm,slb,sam->sijabm", ru, pb.c_bt, mom
    )
    b = np.einsum("slk,sakm->slam", pb.c_bt, rot)  # C_bt R^T
    j[:, 3:12, 3:12] = d_drot_drot.reshape(ns, 9, 9, m_nodes)
    j[:, 3:12, 15:18] = np.einsum("sijlm,slam->sijam", ru, b).reshape(ns, 9, 3, m_nodes)
    # m' = n x r' - l:  d m'/dR = n^ dr'/dR,  d m'/dn = n^ A - r'^,  d m'/dm = 0
    nhat = np.einsum("iqp,sqm->sipm", EPS, n)  # n^_ip = eps_iqp n_q
    drhat = np.einsum("iqp,sqm->sipm", EPS, dr)
    j[:, 15:18, 3:12] = np.einsum("sipm,spkm->sikm", nhat, j[:, 0:3, 3:12])
    j[:, 15:18, 12:15] = np.einsum("sipm,spkm->sikm", nhat, a) - drhat
    j *= (pb.lengths[:, None, None, None] * pb.scale[None, None, :, None]) / pb.scale[
        None, :, None, None
    ]
    full = np.zeros((18 * ns, 18 * ns, m_nodes))
    for i in range(ns):
        full[18 * i : 18 * i + 18, 18 * i : 18 * i + 18] = j[i]
    return full


def _tip_residual(pb: _Problem, yb_last: np.ndarray) -> np.ndarray:
    z = yb_last * pb.scale
    rot, n, mom = z[3:12].reshape(3, 3), z[12:15], z[15:18]
    return np.concatenate(
        [
            (n - pb.f_tip) / pb.scale[12],
            (mom - np.cross(rot @ pb.com, pb.w_tip) - pb.m_tip) / pb.scale[15],
        ]
    )


def bc(pb: _Problem, ya: np.ndarray, yb: np.ndarray) -> np.ndarray:
    """Base clamp (12), continuity at each junction (18 each), tip wrench balance (6)."""
    ns = pb.ns
    ya = ya.reshape(ns, 18)
    yb = yb.reshape(ns, 18)
    base = np.concatenate([ya[0, 0:3] - pb.r0 / pb.scale[0], ya[0, 3:12] - pb.rot0.reshape(9)])
    junctions = (ya[1:] - yb[:-1]).reshape(-1)
    return np.concatenate([base, junctions, _tip_residual(pb, yb[-1])])


def bc_jac(pb: _Problem, ya: np.ndarray, yb: np.ndarray):
    """Exact d(bc)/d(ya) and d(bc)/d(yb)."""
    ns = pb.ns
    nt = 18 * ns
    da = np.zeros((nt, nt))
    db = np.zeros((nt, nt))
    da[0:12, 0:12] = np.eye(12)
    for i in range(ns - 1):
        rows = slice(12 + 18 * i, 12 + 18 * (i + 1))
        da[rows, 18 * (i + 1) : 18 * (i + 2)] = np.eye(18)
        db[rows, 18 * i : 18 * (i + 1)] = -np.eye(18)
    last = 18 * (ns - 1)
    tip_rows = slice(nt - 6, nt)
    db[tip_rows, last + 12 : last + 18] = np.eye(6)
    # d/dR_kl of -((R c) x w)_i / m_unit = -eps_ipq delta_pk c_l w_q ...
    dcw = np.einsum("ikq,l,q->ikl", EPS, pb.com, pb.w_tip).reshape(3, 9)
    db[nt - 3 : nt, last + 3 : last + 12] = -dcw * pb.scale[3] / pb.scale[15]
    return da, db


def straight_guess(pb: _Problem, t: np.ndarray) -> np.ndarray:
    """The straight, undeformed rod carrying its weight and tip loads: (18 ns, len(t))."""
    ns, m_nodes = pb.ns, len(t)
    length = pb.lengths.sum()
    d3 = pb.rot0[:, 2]
    s = pb.s_start[:, None] + t[None, :] * pb.lengths[:, None]  # (ns, m)
    # n(s) = n(L) + int_s^L f;  m(s) = m(L) + (L - s) d3 x n(L) + int_s^L (s' - s) d3 x f + l
    s_end = pb.s_start + pb.lengths
    y = np.zeros((ns, 18, m_nodes))
    for i in range(ns):
        for k, sk in enumerate(s[i]):
            n = pb.f_tip.copy()
            mom = pb.m_tip + np.cross(pb.rot0 @ pb.com, pb.w_tip)
            mom = mom + np.cross((length - sk) * d3, pb.f_tip)
            for jj in range(ns):
                a, b = max(sk, pb.s_start[jj]), s_end[jj]
                if b <= a:
                    continue
                n = n + pb.f[jj] * (b - a)
                arm = 0.5 * (b * b - a * a) - sk * (b - a)  # int_a^b (s' - s) ds'
                mom = mom + np.cross(d3, pb.f[jj]) * arm + pb.lm[jj] * (b - a)
            y[i, 0:3, k] = pb.r0 + sk * d3
            y[i, 3:12, k] = pb.rot0.reshape(9)
            y[i, 12:15, k] = n
            y[i, 15:18, k] = mom
    y /= pb.scale[None, :, None]
    return y.reshape(18 * ns, m_nodes)


@dataclass
class BvpResult:
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    success: bool
    niter: int
    nfev: int
    nodes: int
    message: str
    sol: object


def solve_bvp_full(
    design,
    pressures,
    *,
    nodes: int = DEFAULT_NODES,
    tol: float = DEFAULT_TOL,
    bc_tol: float | None = None,
    max_nodes: int = 100_000,
    exact_jacobian: bool = True,
    tip_force=None,
    tip_moment=None,
) -> BvpResult:
    """Solve the static BVP of ``design`` with scipy's solve_bvp from the straight rod.

    ``nodes`` is the initial mesh per section (each section is its own normalised copy), so a
    mesh node always sits on every junction. ``exact_jacobian`` hands solve_bvp the analytic
    Jacobians of the ODE and boundary conditions (else solve_bvp uses finite differences).
    """
    pb = build_problem(design, pressures, tip_force, tip_moment)
    t = np.linspace(0.0, 1.0, nodes)
    y0 = straight_guess(pb, t)
    count = [0]

    def fun(tt, yy):
        count[0] += 1
        return rhs(pb, tt, yy)

    kwargs = {}
    if exact_jacobian:
        kwargs["fun_jac"] = lambda tt, yy: rhs_jac(pb, tt, yy)
        kwargs["bc_jac"] = lambda ya, yb: bc_jac(pb, ya, yb)
    sol = solve_bvp(
        fun,
        lambda ya, yb: bc(pb, ya, yb),
        t,
        y0,
        tol=tol,
        bc_tol=bc_tol,
        max_nodes=max_nodes,
        **kwargs,
    )
    tip = sol.y[:, -1].reshape(pb.ns, 18)[-1] * pb.scale
    return BvpResult(
        tip_position=tip[0:3].copy(),
        tip_rotation=tip[3:12].reshape(3, 3).copy(),
        success=bool(sol.success),
        niter=int(sol.niter),
        nfev=count[0],
        nodes=len(sol.x),
        message=str(sol.message),
        sol=sol,
    )


def solve_bvp_tip(design, pressures, **kwargs) -> tuple[np.ndarray, bool, int]:
    """Tip position (m, world), success flag and the number of right-hand-side evaluations
    (each over the whole mesh; solve_bvp's own ``niter`` counts mesh refinements only).
    Keyword arguments go to :func:`solve_bvp_full`."""
    res = solve_bvp_full(design, pressures, **kwargs)
    return res.tip_position, res.success, res.nfev


def _main() -> None:  # pragma: no cover - manual check
    import softrod

    design = softrod.load_design("spa_three_chamber_130mm")
    length = design.length
    fine = design.replace({"numerics.steps_per_section": 1024})
    cases = [(0, 0, 0), (70e3, 0, 0), (70e3, 70e3, 0), (20e3, 45e3, 70e3), (70e3, 70e3, 70e3)]
    print(
        f"{'pressures kPa':>22} {'tol':>7} {'nodes':>6} {'nfev':>4} {'ms':>7} "
        f"{'|bvp - ref|/L':>13} {'|softrod - ref|/L':>17}"
    )
    for p in cases:
        ref = softrod.solve_statics(fine, p).tip_position
        sr = softrod.solve_statics(design, p).tip_position
        for tol in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
            t0 = time.perf_counter()
            res = solve_bvp_full(design, p, tol=tol)
            dt = time.perf_counter() - t0
            print(
                f"{str(tuple(x / 1e3 for x in p)):>22} {tol:7.0e} {res.nodes:6d} {res.nfev:4d} "
                f"{dt * 1e3:7.1f} {np.linalg.norm(res.tip_position - ref) / length:13.2e} "
                f"{np.linalg.norm(sr - ref) / length:17.2e}"
            )


if __name__ == "__main__":  # pragma: no cover
    _main()
