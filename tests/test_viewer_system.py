"""The viewer of a system of rods (``softrod.view_system``) without a browser: its re-solves
against ``solve_system`` (warm-started from the equilibrium on screen, and on a frictional
load path continued from it), every rod's tube drawn on its solved centreline, the
platform drawn at its solved pose, the checks before the server starts, and the CLI. The
page in a real Chromium is in tests/test_viewer_browser.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import softrod
from softrod import InputError
from test_viewer import quaternion_matrix, skinned_vertices

pytest.importorskip("viser", reason="needs the viewer extra (viser)")

SYSTEM = "two_spa_platform"


@pytest.fixture(scope="module")
def viewer():
    v = softrod.view_system(SYSTEM, pressure_range=(0, 70e3), environment_map=False)
    yield v
    v.close()


def test_a_move_re_solves_the_system_from_the_equilibrium_on_screen(viewer):
    shown = viewer.solution
    assert shown.converged and viewer.solves >= 1
    p = [[30e3, 0.0, 0.0], [0.0, 10e3, 0.0]]
    sol = viewer.set_inputs(pressures=p)
    # Exactly what solve_system gives from the same warm start.
    same = softrod.solve_system(SYSTEM, p, initial=shown, on_unstable="ignore")
    np.testing.assert_array_equal(sol.platform_position, same.platform_position)
    np.testing.assert_array_equal(viewer.pressures[0], [30e3, 0, 0])
    # The platform is drawn at its solved pose, every rod's tube on its centreline.
    frame = viewer._platform_frame
    np.testing.assert_allclose(frame.position, sol.platform_position, atol=1e-12)
    np.testing.assert_allclose(quaternion_matrix(frame.wxyz), sol.platform_rotation, atol=1e-12)
    for tubes, rod in zip(viewer._tubes, sol.rods, strict=True):
        body = tubes.meshes[1]  # the chambered section
        verts = skinned_vertices(body)
        a, b = np.flatnonzero(rod.section == 1)[[0, -1]]
        centre = rod.position[a : b + 1]
        # Every vertex lies at the outer radius (21.1 mm) from some node of the section:
        # float32 vertices, exact to ~1e-6 m.
        d = np.linalg.norm(verts[:, None, :] - centre[None, :, :], axis=2).min(axis=1)
        assert d.max() < 21.1e-3 + 1e-5
    assert "platform (mm)" in viewer._status.content and "stable: **yes**" in viewer._status.content
    assert repr(viewer).startswith("SystemViewer('two_spa_platform'")


def test_bad_inputs_are_refused_by_name_before_any_move(viewer):
    solves = viewer.solves
    for kwargs, field in (
        ({"pressures": [[300e3, 0, 0], [0, 0, 0]]}, "pressures[0][0]"),
        ({"pressures": [[0, 0], [0, 0, 0]]}, "pressures[0]"),
        ({"pressures": [[0, 0, 0]]}, "pressures"),
        ({"tensions": [[1.0], [1.0]]}, "tensions[0]"),
    ):
        with pytest.raises(InputError) as e:
            viewer.set_inputs(**kwargs)
        assert e.value.field == field, kwargs
    assert viewer.solves == solves
    with pytest.raises(InputError) as e:
        softrod.view_system(SYSTEM, pressures=[[90e3, 0, 0], [0, 0, 0]], pressure_range=(0, 70e3))
    assert e.value.field == "pressures[0][0]"


def test_a_frictional_system_continues_its_load_path():
    table = softrod.load_system("two_fingers_on_table")
    rough = dataclasses.replace(
        table,
        rods=tuple(
            dataclasses.replace(r, design=r.design.replace({"obstacles[0].friction": 0.5}))
            for r in table.rods
        ),
    )
    with softrod.view_system(rough, environment_map=False) as v:
        assert v.frictional
        first = v.set_inputs(pressures=[[20e3], [20e3]])
        second = v.set_inputs(pressures=[[35e3], [35e3]])
        # The second move loads the fingers from where the first left them.
        same = softrod.solve_system(rough, [[35e3], [35e3]], history=first)
        np.testing.assert_array_equal(second.platform_position, same.platform_position)
        assert "rod 0 contact" in v._status.content


def test_a_stiffness_mapped_rod_is_shown_with_its_designs_map(tmp_path):
    """A rod whose section is stiffness-mapped takes its design's map in the viewer's
    re-solves, as in solve_system; without a map the viewer refuses it before the server
    starts, naming the rod."""
    system = softrod.load_system(SYSTEM)
    mapped = system.rods[0].design.replace({"sections[1].law": {"stiffness_map": True}})
    smap = softrod.StiffnessMap.constant((1.4, 0.6, 0.8), 3)
    rod0 = dataclasses.replace(
        system.rods[0], design=mapped.with_stiffness_map(smap.save(tmp_path / "sigma.json"))
    )
    with_map = dataclasses.replace(system, rods=(rod0, system.rods[1]))
    p = [[30e3, 0.0, 0.0], [0.0, 10e3, 0.0]]
    with softrod.view_system(with_map, environment_map=False) as v:
        shown = v.solution
        sol = v.set_inputs(pressures=p)
        same = softrod.solve_system(with_map, p, initial=shown, on_unstable="ignore")
        np.testing.assert_array_equal(sol.platform_position, same.platform_position)
        np.testing.assert_array_equal(sol.rods[0].stiffness_scale, [1.4, 0.6, 0.8])
    bare = dataclasses.replace(
        system, rods=(dataclasses.replace(system.rods[0], design=mapped), system.rods[1])
    )
    with pytest.raises(InputError, match="never assumed to be 1") as e:
        softrod.view_system(bare, environment_map=False)
    assert e.value.field == "rods[0].design.stiffness_map"


def test_view_system_command_refuses_a_bad_range(run):
    result = run("view-system", SYSTEM, "--pressure-range", "70kPa:0")
    assert result.exit_code == 2 and "--pressure-range" in result.stderr
