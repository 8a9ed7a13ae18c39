"""PyElastica 1.0's Cosserat rod with softrod's linear constitutive law (benchmark only).

PyElastica 1.0 (``elastica/rod/cosserat_rod.py``) divides the internal force by the dilatation
e = |r_s| (``cosserat_internal_stress /= dilatation``), the bending/twist couple by the Voronoi
dilatation cubed (``internal_couple * 1 / voronoi_dilatation**3``), and the rotary inertia by
e (``J omega / e``, the ``unsteady_dilatation`` term, ``alpha = J^-1 tau e``): the law of
Gazzola, Dudte, McCormick, Mahadevan, "Forward and inverse problems in the mechanics of soft
filaments", Royal Society Open Science 5:171628, 2018, DOI 10.1098/rsos.171628, for an
incompressible rod. softrod's law is n = R K_se (v - e3),
m = R K_bt u with constant rho I. ``law("softrod")`` swaps PyElastica's three kernels for copies
with those factors removed (everything else, the discretisation, the clamp, the lumped masses
and PositionVerlet, stays PyElastica's), so that both codes model the same continuum rod.
Imported only when PyElastica is installed.
"""

from __future__ import annotations

import contextlib

import elastica.rod.cosserat_rod as cr
import numba
import numpy as np
from elastica._calculus import (
    difference_kernel_for_block_structure,
    quadrature_kernel_for_block_structure,
)
from elastica._linalg import _batch_cross, _batch_matvec

_ORIGINAL = (cr._compute_internal_forces, cr._compute_internal_torques, cr._update_accelerations)


def kernels(force_over_e: bool, couple_over_e3: bool, inertia_over_e: bool):
    """PyElastica's three kernels with each of its dilatation factors on or off: all three on
    is PyElastica 1.0's law (the same arithmetic, to the last digit in the cantilever),
    all off softrod's. The flags are compile-time constants of the closures."""
    fe, ce, je = bool(force_over_e), bool(couple_over_e3), bool(inertia_over_e)

    @numba.njit(cache=False)
    def forces(
        position_collection,
        volume,
        lengths,
        tangents,
        radius,
        rest_lengths,
        rest_voronoi_lengths,
        dilatation,
        voronoi_dilatation,
        director_collection,
        sigma,
        rest_sigma,
        shear_matrix,
        internal_stress,
        internal_forces,
        ghost_elems_idx,
    ):
        cr._compute_internal_shear_stretch_stresses_from_model(
            position_collection,
            volume,
            lengths,
            tangents,
            radius,
            rest_lengths,
            rest_voronoi_lengths,
            dilatation,
            voronoi_dilatation,
            director_collection,
            sigma,
            rest_sigma,
            shear_matrix,
            internal_stress,
        )
        blocksize = internal_stress.shape[1]
        lab = np.zeros((3, blocksize))
        for i in range(3):
            for j in range(3):
                for k in range(blocksize):
                    lab[i, k] += director_collection[j, i, k] * internal_stress[j, k]
        if fe:  # PyElastica: Q^T S sigma / e
            lab /= dilatation
        internal_forces[:] = difference_kernel_for_block_structure(lab, ghost_elems_idx)

    @numba.njit(cache=False)
    def torques(
        position_collection,
        velocity_collection,
        tangents,
        lengths,
        rest_lengths,
        director_collection,
        rest_voronoi_lengths,
        bend_matrix,
        rest_kappa,
        kappa,
        voronoi_dilatation,
        mass_second_moment_of_inertia,
        omega_collection,
        internal_stress,
        internal_couple,
        dilatation,
        dilatation_rate,
        internal_torques,
        ghost_voronoi_idx,
    ):
        cr._compute_internal_bending_twist_stresses_from_model(
            director_collection,
            rest_voronoi_lengths,
            internal_couple,
            bend_matrix,
            kappa,
            rest_kappa,
        )
        cr._compute_dilatation_rate(
            position_collection, velocity_collection, lengths, rest_lengths, dilatation_rate
        )
        scale = np.ones(voronoi_dilatation.shape[0])
        if ce:  # PyElastica: B kappa / e_v^3
            scale = 1.0 / voronoi_dilatation**3
        couple_2d = difference_kernel_for_block_structure(
            internal_couple * scale, ghost_voronoi_idx
        )
        couple_3d = quadrature_kernel_for_block_structure(
            _batch_cross(kappa, internal_couple) * rest_voronoi_lengths * scale, ghost_voronoi_idx
        )
        # v x n, v = e Q t: PyElastica's (Q t) x n_L pairs with its n_L / e
        shear_couple = _batch_cross(_batch_matvec(director_collection, tangents), internal_stress)
        if fe:
            shear_couple *= rest_lengths
        else:
            shear_couple *= rest_lengths * dilatation
        j_omega = _batch_matvec(mass_second_moment_of_inertia, omega_collection)
        if je:  # PyElastica: J omega / e and the de/dt term
            j_omega /= dilatation
        internal_torques[:] = (
            couple_2d + couple_3d + shear_couple + _batch_cross(j_omega, omega_collection)
        )
        if je:
            internal_torques[:] += j_omega * dilatation_rate / dilatation

    @numba.njit(cache=False)
    def accelerations(
        acceleration_collection,
        internal_forces,
        external_forces,
        mass,
        alpha_collection,
        inv_mass_second_moment_of_inertia,
        internal_torques,
        external_torques,
        dilatation,
    ):
        for i in range(3):
            for k in range(internal_forces.shape[1]):
                acceleration_collection[i, k] = (
                    internal_forces[i, k] + external_forces[i, k]
                ) / mass[k]
        alpha_collection *= 0.0
        for i in range(3):
            for j in range(3):
                for k in range(internal_torques.shape[1]):
                    f = dilatation[k] if je else 1.0  # PyElastica: J^-1 tau e
                    alpha_collection[i, k] += (
                        inv_mass_second_moment_of_inertia[i, j, k]
                        * (internal_torques[j, k] + external_torques[j, k])
                        * f
                    )

    return forces, torques, accelerations


_CACHE: dict = {}


def _variant(flags: tuple) -> tuple:
    if flags not in _CACHE:
        _CACHE[flags] = kernels(*flags)
    return _CACHE[flags]


# Variants: which of PyElastica's dilatation factors are on (force / e, couple / e^3, J / e).
VARIANTS = {
    "softrod": (False, False, False),
    "force/e only": (True, False, False),
    "couple/e^3 only": (False, True, False),
    "inertia/e only": (False, False, True),
    "force/e and couple/e^3": (True, True, False),
}


@contextlib.contextmanager
def law(name: str):
    """``"pyelastica"``: PyElastica 1.0 as shipped (its own kernels); ``"softrod"``:
    softrod's linear law; or another of VARIANTS. The kernels are module globals of
    elastica.rod.cosserat_rod, looked up on every step."""
    if name == "pyelastica":
        chosen = _ORIGINAL
    elif name in VARIANTS:
        chosen = _variant(VARIANTS[name])
    else:
        raise ValueError(f"unknown law {name!r}")
    saved = (cr._compute_internal_forces, cr._compute_internal_torques, cr._update_accelerations)
    cr._compute_internal_forces, cr._compute_internal_torques, cr._update_accelerations = chosen
    try:
        yield
    finally:
        cr._compute_internal_forces, cr._compute_internal_torques, cr._update_accelerations = saved
