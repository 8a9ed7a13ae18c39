"""Stiffness-mapped rods in a system's motion (sigma of paper 001 eq. 13, per rod, from its
design's map or ``stiffness_maps=``, evaluated in the core at every step's pressures;
docs/dynamics.md "Systems of rods", docs/stiffness-map.md "Systems of rods"): the start is
``solve_system``'s equilibrium with the same maps, a damped run settles on it, a constant
map equals the rod with its stiffness factors multiplied, and maps that do not fit are
refused by name (sigma is never assumed to be 1)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import softrod
from conftest import assert_clean_error
from softrod import InputError, StiffnessMap, SystemTrajectory
from system_cases import network_map, table_map, two_mapped_rods

pytestmark = pytest.mark.filterwarnings("error")

#: Pressures inside the table's 0..60 kPa, different on every rod and channel group.
P = [[40e3, 0.0, 10e3], [0.0, 20e3, 0.0]]
ZERO = [[0.0] * 3, [0.0] * 3]
#: The start is solve_system's equilibrium refined on the collocation grids; the two
#: discretisations differ by O(h^4) of the 130 mm rods (measured 1.7e-9 m here, as the
#: unmapped system's start test): 1e-8 m.
GRIDS = 1e-8  # m


def damped(system, tau="50 ms"):
    """``system`` with every rod's Kelvin-Voigt damping time ``tau``."""
    rods = tuple(
        dataclasses.replace(r, design=r.design.replace({"dynamics.damping_time": tau}))
        for r in system.rods
    )
    return dataclasses.replace(system, rods=rods)


def one_mapped(system=None):
    """The bundled system with rod 0's body section mapped, rod 1 as bundled."""
    system = softrod.load_system("two_spa_platform") if system is None else system
    both = two_mapped_rods(system)
    return dataclasses.replace(system, rods=(both.rods[0], system.rods[1]))


@pytest.fixture(scope="module")
def mapped_system():
    return damped(two_mapped_rods())


def test_the_start_is_the_static_equilibrium_with_the_same_maps(mapped_system):
    maps = [table_map(), table_map()]
    rest = softrod.solve_system(mapped_system, P, stiffness_maps=maps)
    traj = softrod.simulate_system(mapped_system, P, "40 ms", stiffness_maps=maps)
    assert np.abs(traj.platform_position[0] - rest.platform_position).max() < GRIDS
    # The rotation's entries are O(1): the same bound.
    assert np.abs(traj.platform_rotation[0] - rest.platform_rotation).max() < GRIDS
    # Held inputs: the start stays at rest (Newton at tol = 1e-9 of the unknowns, whose
    # corrections the kept matrix drives to ~1e-14 m/s; measured 3e-14 m/s).
    assert np.abs(traj.platform_velocity).max() < 1e-10
    assert np.abs(traj.platform_position - traj.platform_position[0]).max() < 1e-12
    # sigma acts: with unit maps the static platform sits millimetres away.
    ones = [StiffnessMap.constant((1.0, 1.0, 1.0), 3)] * 2
    unit = softrod.solve_system(mapped_system, P, stiffness_maps=ones)
    assert np.linalg.norm(unit.platform_position - rest.platform_position) > 1e-3


def test_a_damped_system_settles_on_the_mapped_equilibrium(mapped_system):
    maps = [table_map(), table_map()]
    rest = softrod.solve_system(mapped_system, P, stiffness_maps=maps)
    # Released from rest at zero pressures, then P held: the map is evaluated at every
    # step's pressures, so sigma jumps from sigma(0) to sigma(P) with the step.
    sim = softrod.SystemSimulation(mapped_system, ZERO, stiffness_maps=maps)
    assert sim.stiffness_maps == tuple(maps)
    chunk = 0.2  # s
    speeds = [np.inf]
    traj = None
    # Settle criterion: the platform's speed below SETTLED (m/s), in chunks of 0.2 s.
    settled = 1e-6  # m/s
    while speeds[-1] > settled:
        assert sim.time < 3.0, f"not settled after {sim.time:g} s: {speeds[-3:]} m/s"
        traj = sim.run(P, chunk)
        speeds.append(float(np.linalg.norm(traj.platform_velocity[-1])))
    assert traj is not None
    # Near rest every mode decays exponentially, the slowest last: x - x_eq = -T v with T
    # its time constant, which the last chunk measures (T = chunk / ln(v0 / v1); 0.14 s
    # here). The distance left is then T |v| (< 1.4e-7 m), plus the grids' difference
    # between the dynamics' equilibrium and solve_system's; a factor 2 on T covers a
    # second mode not yet decayed.
    slowest = chunk / np.log(speeds[-2] / speeds[-1])
    assert 0 < slowest < 0.5
    left = 2 * slowest * speeds[-1] + GRIDS
    assert np.linalg.norm(traj.platform_position[-1] - rest.platform_position) < left
    # The platform travelled millimetres, so the check is not the start's.
    start = softrod.solve_system(mapped_system, ZERO, stiffness_maps=maps)
    assert np.linalg.norm(rest.platform_position - start.platform_position) > 1e-3


def test_a_constant_map_is_the_rod_with_its_stiffness_multiplied():
    # sigma = (c, c, c) scales c_e EA and c_b EI of the mapped body section by c
    # (docs/stiffness-map.md, "What is scaled"; shear and torsion stay): the same rod
    # unmapped with c_e = c_b = c (their default is 1) is an independent model of it, and
    # the Kelvin-Voigt damping B = tau K follows the scaled K in both.
    c = 1.4
    bundled = damped(softrod.load_system("two_spa_platform"))
    mapped = one_mapped(bundled)
    scaled_rod = dataclasses.replace(
        bundled.rods[0],
        design=bundled.rods[0].design.replace({"sections[1].c_e": c, "sections[1].c_b": c}),
    )
    scaled = dataclasses.replace(bundled, rods=(scaled_rod, bundled.rods[1]))

    def ramp(t):
        return [[min(t / 0.02, 1.0) * 40e3, 0.0, 0.0], [0.0, 0.0, 10e3]]

    smap = StiffnessMap.constant((c, c, c), 3)
    # Newton to 1e-12 of the unknowns: the runs differ only in the rounding of c EA sigma
    # against (c c_e) EA, which moves each step's solution by ~tol * L = 1e-13 m
    # (measured 4e-15 m over 30 steps): 1e-12 m.
    a = softrod.simulate_system(mapped, ramp, 0.06, stiffness_maps=[smap, None], tol=1e-12)
    b = softrod.simulate_system(scaled, ramp, 0.06, tol=1e-12)
    same = 1e-12  # m
    np.testing.assert_allclose(a.platform_position, b.platform_position, rtol=0, atol=same)
    np.testing.assert_allclose(a.shapes[0], b.shapes[0], rtol=0, atol=same)
    np.testing.assert_allclose(a.platform_rotation, b.platform_rotation, rtol=0, atol=same)
    # The energies (mJ) likewise, to Newton's tolerance of the states.
    np.testing.assert_allclose(a.elastic, b.elastic, rtol=1e-9)
    np.testing.assert_allclose(a.dissipated, b.dissipated, rtol=1e-9, atol=1e-15)
    # The ramp moved the platform millimetres, and sigma acted: sigma = 1 moves it elsewhere.
    assert np.linalg.norm(a.platform_position[-1] - a.platform_position[0]) > 1e-3
    unit = softrod.simulate_system(
        mapped, ramp, 0.06, stiffness_maps=[StiffnessMap.constant((1, 1, 1), 3), None]
    )
    assert np.abs(unit.platform_position - a.platform_position).max() > 1e-4


def test_the_design_map_file_is_used_and_state_restores(tmp_path):
    smap = table_map()
    file = smap.save(tmp_path / "sigma.json")
    bundled = softrod.load_system("two_spa_platform")
    mapped = one_mapped(bundled)
    with_file = dataclasses.replace(
        mapped,
        rods=(
            dataclasses.replace(
                mapped.rods[0], design=mapped.rods[0].design.with_stiffness_map(file)
            ),
            mapped.rods[1],
        ),
    )
    given = softrod.simulate_system(mapped, P, 0.01, stiffness_maps=[smap, None])
    from_file = softrod.simulate_system(with_file, P, 0.01)
    assert np.array_equal(given.platform_position, from_file.platform_position)
    # A saved state continues bit for bit, the map evaluated again at every step.
    sim = softrod.SystemSimulation(with_file, ZERO)
    sim.run(P, 0.01)
    state = sim.save()
    first = sim.run([[30e3, 5e3, 0], [0, 0, 0]], 0.01)
    sim.restore(state)
    again = sim.run([[30e3, 5e3, 0], [0, 0, 0]], 0.01)
    assert np.array_equal(first.platform_position, again.platform_position)
    # The command line runs the system file's maps.
    path = with_file.save(tmp_path / "mapped_system.toml")
    loaded = softrod.load_system(path)
    assert loaded.rods[0].design.stiffness_map is not None
    from click.testing import CliRunner
    from softrod.cli import main

    out = tmp_path / "motion.npz"
    result = CliRunner().invoke(
        main,
        [
            "simulate-system",
            str(path),
            "-p",
            "40kPa,0,10kPa",
            "-p",
            "0,20kPa,0",
            "--t-end",
            "10 ms",
            "--out",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.output
    cli = SystemTrajectory.load(out, loaded)
    sim = softrod.SystemSimulation(loaded, dt="2 ms")
    api = SystemTrajectory.concat([sim.state(), sim.run(P, 0.01)])
    assert np.array_equal(cli.platform_position, api.platform_position)
    # A bare mapped rod in a system file is refused by the command line, by the rod.
    bare = one_mapped(bundled).save(tmp_path / "bare_system.toml")
    result = CliRunner().invoke(
        main, ["simulate-system", str(bare), "--t-end", "10 ms", "--out", str(out)]
    )
    assert_clean_error(result, 2, "rods[0].design.stiffness_map", "never assumed to be 1")


def test_a_mapped_rod_without_a_map_is_refused_by_the_rod():
    bare = one_mapped()
    for call in (
        lambda: softrod.simulate_system(bare, P, 0.01),
        lambda: softrod.SystemSimulation(bare, P),
        lambda: softrod.SystemSimulation(bare, P, stiffness_maps=[None, None]),
    ):
        with pytest.raises(InputError, match="never assumed to be 1") as e:
            call()
        assert e.value.field == "rods[0].design.stiffness_map"
        assert "stiffness_maps=" in e.value.rule


@pytest.mark.parametrize(
    "maps, field, words",
    [
        (StiffnessMap.constant((1, 1, 1), 3), "stiffness_maps", "one per rod"),
        ([None], "stiffness_maps", "one per rod"),
        (["table", None], "stiffness_maps[0]", "softrod.StiffnessMap"),
        ([StiffnessMap.constant((1, 1, 1), 2), None], "stiffness_maps[0]", "takes 2"),
        # A map the core cannot evaluate at every step: a network (tabulate it first).
        ([table_map(), network_map()], "stiffness_maps[1]", "at every step"),
        (
            [
                table_map(),
                StiffnessMap.from_table(
                    [np.array([0.0, 3e4, 6e4])] * 3, np.ones((3, 3, 3, 3)), method="linear"
                ),
            ],
            "stiffness_maps[1]",
            "pchip",
        ),
    ],
)
def test_bad_stiffness_maps_name_the_entry(maps, field, words):
    system = two_mapped_rods()
    for call in (
        lambda: softrod.simulate_system(system, ZERO, 0.01, stiffness_maps=maps),
        lambda: softrod.SystemSimulation(system, ZERO, stiffness_maps=maps),
    ):
        with pytest.raises(InputError, match=words) as e:
            call()
        assert e.value.field == field


def test_a_map_for_an_unmapped_rod_is_refused():
    system = one_mapped()
    ones = StiffnessMap.constant((1.0, 1.0, 1.0), 3)
    with pytest.raises(InputError, match="no effect") as e:
        softrod.SystemSimulation(system, ZERO, stiffness_maps=[ones, ones])
    assert e.value.field == "stiffness_maps[1]"


def test_pressures_outside_the_table_are_refused_naming_the_rod():
    system = two_mapped_rods()
    maps = [table_map(), table_map()]
    # The table ends at 60 kPa and refuses beyond it (outside="raise"): at the start ...
    with pytest.raises(InputError) as e:
        softrod.SystemSimulation(system, [[0, 0, 0], [0, 0, 70e3]], stiffness_maps=maps)
    assert e.value.field == "rods[1].pressures[2]"
    # ... and at a step, where the run stops with the steps before it kept.
    sim = softrod.SystemSimulation(system, ZERO, stiffness_maps=maps)
    with pytest.raises(InputError) as e:
        sim.run(lambda t: [[0, 0, 0], [0, 0, 0 if t < 0.005 else 70e3]], 0.01)
    assert e.value.field == "rods[1].pressures[2]"
    assert sim.time == pytest.approx(0.004, rel=1e-12)


def test_a_state_restores_only_with_the_same_maps():
    # The state holds the motion, not the material: restored into a simulation whose maps
    # differ it would continue another model's run as if it were this one's, so it is refused
    # (the maps' numbers are part of the state's fingerprint), for systems and single rods.
    system = one_mapped()
    sim = softrod.SystemSimulation(system, ZERO, stiffness_maps=[table_map(), None])
    state = sim.save()
    other = softrod.SystemSimulation(
        system, ZERO, stiffness_maps=[StiffnessMap.constant((1.0, 1.0, 1.0), 3), None]
    )
    with pytest.raises(InputError, match="stiffness maps") as info:
        other.restore(state)
    assert info.value.field == "state"
    same = softrod.SystemSimulation(system, ZERO, stiffness_maps=[table_map(), None])
    same.restore(state)  # the same numbers: accepted
    sim.copy().restore(state)

    design = system.rods[0].design
    rod = softrod.Simulation(design, [0.0] * 3, stiffness_map=table_map())
    rod_state = rod.state()
    unit = StiffnessMap.constant((1.0, 1.0, 1.0), 3)
    with pytest.raises(InputError, match="another stiffness map"):
        softrod.Simulation(design, [0.0] * 3, stiffness_map=unit).restore(rod_state)
    rod.copy().restore(rod_state)
    softrod.Simulation(design, [0.0] * 3, stiffness_map=table_map()).restore(rod_state)
