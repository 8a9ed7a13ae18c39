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


def test_view_system_command_refuses_a_bad_range(run):
    result = run("view-system", SYSTEM, "--pressure-range", "70kPa:0")
    assert result.exit_code == 2 and "--pressure-range" in result.stderr
