"""Stiffness-mapped rods in a system's statics (sigma of paper 001 eq. 13, per rod, from its
design's map or ``stiffness_maps=``): a one-rod system equals the free mapped rod under the
platform's load, batch rows are bitwise the single solves for table and network maps, and
a mapped rod without a map is refused by name (sigma is never assumed to be 1)."""

import numpy as np
import pytest
import softrod
from softrod import (
    InputError,
    Platform,
    StiffnessMap,
    System,
    SystemRod,
    solve_statics,
    solve_system,
    solve_system_batch,
)
from system_cases import mapped, network_map, table_map, two_mapped_rods

pytestmark = pytest.mark.filterwarnings("error")

#: Both solves stop at a scaled residual of 1e-10 (SolverOptions.tol) on a 130 mm rod:
#: their tips agree to ~1e-11 m; 1e-9 m leaves two digits for the different unknowns
#: (the system's 12 against the free rod's 3) and conditioning. A missing sigma moves the
#: tip by millimetres.
SAME_EQUILIBRIUM = 1e-9  # m


def one_rod_system(design) -> System:
    """The rod holding a massless platform at its unloaded tip, the platform frame its tip
    frame: the platform's load is the rod's tip load."""
    rest = solve_statics(design, [0.0, 0.0, 0.0], stiffness_map=StiffnessMap.constant((1, 1, 1), 3))
    platform = Platform(position=rest.tip_position, rotation=rest.tip_rotation, mass=0.0)
    return System("one_rod", (SystemRod(design, attachment=np.zeros(3)),), platform)


def test_one_rod_system_equals_the_free_mapped_rod_under_the_platform_load():
    design = mapped()
    smap = table_map()
    system = one_rod_system(design)
    force, moment = np.array([0.05, -0.02, 0.03]), np.array([0.0, 1e-3, -2e-4])
    for p in ([30e3, 0.0, 0.0], [10e3, 40e3, 5e3]):
        free = solve_statics(design, p, tip_force=force, tip_moment=moment, stiffness_map=smap)
        sol = solve_system(
            system, [p], platform_force=force, platform_moment=moment, stiffness_maps=[smap]
        )
        rod = sol.rods[0]
        np.testing.assert_array_equal(rod.stiffness_scale, smap(np.array([p]))[0])
        np.testing.assert_array_equal(rod.stiffness_scale, free.stiffness_scale)
        np.testing.assert_allclose(rod.position, free.position, rtol=0, atol=SAME_EQUILIBRIUM)
        np.testing.assert_allclose(sol.platform_position, free.tip_position, atol=SAME_EQUILIBRIUM)
        # The platform's reaction on the tip is its load (its balance converged to a
        # scaled residual of 1e-10 of forces of order 0.1 N; 1e-9 N leaves a digit).
        np.testing.assert_allclose(rod.tip_reaction_force, force, atol=1e-9)
        # sigma acts: the same rod with sigma = 1 ends millimetres away.
        unit = solve_statics(
            design,
            p,
            tip_force=force,
            tip_moment=moment,
            stiffness_map=StiffnessMap.constant((1, 1, 1), 3),
        )
        assert np.linalg.norm(unit.tip_position - free.tip_position) > 1e-3


def test_the_design_map_file_is_used_and_a_mapped_rod_without_one_is_refused(tmp_path):
    smap = table_map()
    file = smap.save(tmp_path / "sigma.json")
    with_file = mapped().with_stiffness_map(file)
    p = [20e3, 0.0, 35e3]
    given = solve_system(one_rod_system(with_file), [p])
    np.testing.assert_array_equal(given.rods[0].stiffness_scale, smap(np.array([p]))[0])
    # The argument replaces the design's map, as solve_statics's stiffness_map= does.
    ones = StiffnessMap.constant((1.0, 1.0, 1.0), 3)
    replaced = solve_system(one_rod_system(with_file), [p], stiffness_maps=[ones])
    np.testing.assert_array_equal(replaced.rods[0].stiffness_scale, [1.0, 1.0, 1.0])
    assert np.linalg.norm(replaced.platform_position - given.platform_position) > 1e-3
    # No map anywhere: refused by the rod, with the rule, in every statics entry point.
    bare = one_rod_system(mapped())
    for call in (
        lambda: solve_system(bare, [p]),
        lambda: solve_system_batch(bare, [[p]]),
        lambda: solve_system(bare, [p], stiffness_maps=[None]),
    ):
        with pytest.raises(InputError, match="never assumed to be 1") as e:
            call()
        assert e.value.field == "rods[0].design.stiffness_map"
        assert "stiffness_maps=" in e.value.rule


def test_batch_rows_are_the_single_solves_with_table_and_network_maps():
    system = two_mapped_rods()
    maps = [table_map(), network_map()]
    rows = np.array(
        [
            [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
            [[30e3, 0.0, 10e3], [0.0, 0.0, 0.0]],
            [[0.0, 25e3, 0.0], [20e3, 5e3, 0.0]],
            [[15e3, 15e3, 15e3], [0.0, 30e3, 12e3]],
        ]
    )
    batch = solve_system_batch(system, rows, stiffness_maps=maps, threads=2)
    assert batch.converged.all()
    for i, smap in enumerate(maps):
        np.testing.assert_array_equal(batch.stiffness_scale[i], smap(rows[:, i, :]))
    for k, row in enumerate(rows):
        single = solve_system(system, row, stiffness_maps=maps)
        np.testing.assert_array_equal(batch.platform_position[k], single.platform_position)
        np.testing.assert_array_equal(batch.platform_rotation[k], single.platform_rotation)
        np.testing.assert_array_equal(batch.unknowns[k], single.unknowns)
        for i, rod in enumerate(single.rods):
            np.testing.assert_array_equal(batch.stiffness_scale[i][k], rod.stiffness_scale)
            np.testing.assert_array_equal(batch.tip_position[k, i], rod.tip_position)
    frame = batch.to_frame()
    np.testing.assert_array_equal(frame["rod1_sigma_bend_x"], batch.stiffness_scale[1][:, 1])
    assert batch.metadata["stiffness_maps"] == [repr(m) for m in maps]
    # sigma acts on the platform: with unit maps it sits elsewhere.
    ones = [StiffnessMap.constant((1.0, 1.0, 1.0), 3)] * 2
    unit = solve_system_batch(system, rows[1:], stiffness_maps=ones)
    assert np.abs(unit.platform_position - batch.platform_position[1:]).max() > 1e-3


def test_a_system_without_mapped_rods_reports_no_sigma():
    system = softrod.load_system("two_spa_platform")
    batch = solve_system_batch(system, np.zeros((1, 2, 3)))
    assert batch.stiffness_scale == (None, None)
    assert not any("sigma" in c for c in batch.to_frame().columns)
    np.testing.assert_array_equal(
        solve_system(system, [[0.0] * 3] * 2).rods[0].stiffness_scale, [1.0, 1.0, 1.0]
    )


@pytest.mark.parametrize(
    "maps, field, words",
    [
        (StiffnessMap.constant((1, 1, 1), 3), "stiffness_maps", "one per rod"),
        ([None], "stiffness_maps", "one per rod"),
        (["table", None], "stiffness_maps[0]", "softrod.StiffnessMap"),
        ([StiffnessMap.constant((1, 1, 1), 2), None], "stiffness_maps[0]", "takes 2"),
    ],
)
def test_bad_stiffness_maps_name_the_entry(maps, field, words):
    system = two_mapped_rods()
    with pytest.raises(InputError, match=words) as e:
        solve_system(system, np.zeros((2, 3)), stiffness_maps=maps)
    assert e.value.field == field


def test_a_map_for_an_unmapped_rod_is_refused():
    system = softrod.load_system("two_spa_platform")
    ones = StiffnessMap.constant((1.0, 1.0, 1.0), 3)
    with pytest.raises(InputError, match="no effect") as e:
        solve_system_batch(system, np.zeros((1, 2, 3)), stiffness_maps=[None, ones])
    assert e.value.field == "stiffness_maps[1]"


def test_a_map_refusing_a_row_names_the_rod():
    system = two_mapped_rods()
    # The table ends at 60 kPa and refuses beyond it (outside="raise").
    rows = np.zeros((2, 2, 3))
    rows[1, 1, 2] = 70e3
    with pytest.raises(InputError) as e:
        solve_system_batch(system, rows, stiffness_maps=[table_map(), table_map()])
    assert e.value.field.startswith("rods[1].pressures[1]")


def test_the_core_refuses_bad_sigma_arrays_by_row_and_rod():
    from softrod import _core
    from softrod.system import _batch_entries, _platform_args

    system = two_mapped_rods()
    entries, platform = _batch_entries(system), _platform_args(system, None, None)
    p = np.zeros((2, 6))
    sigma = np.ones((2, 2, 3))
    sigma[1, 0, 2] = np.nan
    for call in (_core.solve_rod_system_batch, _core.rod_system_sensitivity_batch):
        extra = {} if call is _core.solve_rod_system_batch else {"params": []}
        with pytest.raises(InputError) as e:
            call(entries, platform, p, stiffness_scale=sigma, **extra)
        assert e.value.field == "row 1: rods[0].stiffness_scale[2]"
        with pytest.raises(InputError) as e:
            call(entries, platform, p, stiffness_scale=np.ones((2, 3, 2)), **extra)
        assert e.value.field == "stiffness_scale"
        with pytest.raises(InputError) as e:
            call(entries, platform, p, stiffness_scale=np.ones((3, 2, 3)), **extra)
        assert e.value.field == "stiffness_scale"
        # No sigma for a mapped rod: never assumed to be 1.
        with pytest.raises(InputError, match="never assumed to be 1") as e:
            call(entries, platform, p, **extra)
        assert e.value.field == "rods[0].stiffness_scale"
    # The single solve's entries: (rod, pressures, tensions, then the batch entry's rest).
    rods = [(e[0], [0.0] * 3, [], *e[1:]) for e in entries]
    with pytest.raises(InputError) as e:
        _core.solve_rod_system(rods, platform, stiffness_scale=[[1.0, 1.0, 1.0], None])
    assert e.value.field == "rods[1].stiffness_scale"
    with pytest.raises(InputError) as e:
        _core.solve_rod_system(rods, platform, stiffness_scale=[[1.0, 0.0, 1.0], [1.0] * 3])
    assert e.value.field == "rods[0].stiffness_scale[1]"
    with pytest.raises(InputError) as e:
        _core.solve_rod_system(rods, platform, stiffness_scale=[[1.0] * 3])
    assert e.value.field == "stiffness_scale"
