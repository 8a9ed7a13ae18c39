"""PyElastica 1.0's Cosserat rod with softrod's linear constitutive law (benchmark only).

PyElastica 1.0 (``elastica/rod/cosserat_rod.py``) divides the internal force by the dilatation
e = |r_s| (``cosserat_internal_stress /= dilatation``), the bending/twist couple by the Voronoi
dilatation cubed (``internal_couple * 1 / voronoi_dilatation**3``), and the rotary inertia by
e (``J omega / e``, the ``unsteady_dilatation`` term, ``alpha = J^-1 tau e``): the law of
Gazzola et al. 2018 for an incompressible rod. softrod's law is n = R K_se (v - e3),
m = R K_bt u with constant rho I. ``softrod_law()`` swaps PyElastica's three kernels for copies
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


@numba.njit(cache=True)
def _linear_forces(
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
    # n = Q^T S sigma, not divided by the dilatation
    internal_forces[:] = difference_kernel_for_block_structure(lab, ghost_elems_idx)


@numba.njit(cache=True)
def _linear_torques(
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
    # m = B kappa, not divided by the Voronoi dilatation cubed
    couple_2d = difference_kernel_for_block_structure(internal_couple, ghost_voronoi_idx)
    couple_3d = quadrature_kernel_for_block_structure(
        _batch_cross(kappa, internal_couple) * rest_voronoi_lengths, ghost_voronoi_idx
    )
    # v x n with v = e Q t (PyElastica's (Q t) x n_L pairs with its n_L / e)
    shear_couple = _batch_cross(_batch_matvec(director_collection, tangents), internal_stress) * (
        rest_lengths * dilatation
    )
    # constant rotary inertia: (J omega) x omega, no J / e and no de/dt term
    j_omega = _batch_matvec(mass_second_moment_of_inertia, omega_collection)
    internal_torques[:] = (
        couple_2d + couple_3d + shear_couple + _batch_cross(j_omega, omega_collection)
    )


@numba.njit(cache=True)
def _linear_accelerations(
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
            acceleration_collection[i, k] = (internal_forces[i, k] + external_forces[i, k]) / mass[
                k
            ]
    alpha_collection *= 0.0
    for i in range(3):
        for j in range(3):
            for k in range(internal_torques.shape[1]):
                # J^-1 tau, not multiplied by the dilatation
                alpha_collection[i, k] += inv_mass_second_moment_of_inertia[i, j, k] * (
                    internal_torques[j, k] + external_torques[j, k]
                )


@contextlib.contextmanager
def law(name: str):
    """``"pyelastica"``: PyElastica 1.0 as shipped; ``"softrod"``: softrod's linear law.
    The kernels are module globals of elastica.rod.cosserat_rod, looked up on every step."""
    if name == "pyelastica":
        kernels = _ORIGINAL
    elif name == "softrod":
        kernels = (_linear_forces, _linear_torques, _linear_accelerations)
    else:
        raise ValueError(f"unknown law {name!r}")
    saved = (cr._compute_internal_forces, cr._compute_internal_torques, cr._update_accelerations)
    cr._compute_internal_forces, cr._compute_internal_torques, cr._update_accelerations = kernels
    try:
        yield
    finally:
        cr._compute_internal_forces, cr._compute_internal_torques, cr._update_accelerations = saved
