"""What every softrod viewer shares: the viser server and its page address, one solve per
burst of slider moves (moves that arrive while a solve runs are merged), screenshots, and
the drawing of a rod's sections as skinned tubes and of load arrows (docs/viewer.md)."""

from __future__ import annotations

import contextlib
import io
import socket
import threading
import time
from pathlib import Path

import numpy as np

from ..errors import InputError, design_error
from ..io import as_path
from . import geometry as geo


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on ``host`` right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


class Tubes:
    """One rod's sections drawn as skinned tubes under ``prefix`` (one mesh per section,
    made at its first draw, its bones the section's nodes)."""

    def __init__(self, scene, looks, prefix: str = "/rod"):
        self.scene, self.looks, self.prefix = scene, looks, prefix
        self.meshes: list = [None] * len(looks)

    def draw(self, s, position, rotation, section) -> None:
        """Each section's tube as a skinned mesh with one bone per node: a new shape moves
        the bones only (each ring rides rigidly on its node's frame, so the tube is exact).
        The browser applies bone poses in the animation frame that receives them, while new
        vertex arrays go through the page's React tree and reach the screen one frame later
        (docs/viewer.md, "Responsiveness"). A section whose node count changes (another grid:
        a trajectory's stored shapes) gets a new mesh."""
        ranges = geo.node_ranges(np.asarray(section), len(self.looks))
        q = geo.wxyz(rotation)
        for k, (lk, rng) in enumerate(zip(self.looks, ranges, strict=True)):
            mesh = self.meshes[k]
            if rng is None or rng[1] == rng[0]:  # none, or one node: no tube (not a disc)
                if mesh is not None:
                    mesh.visible = False
                continue
            a, b = rng
            n = b - a + 1
            if mesh is None or len(mesh.bones) != n:
                if mesh is not None:
                    mesh.remove()
                self.meshes[k] = self.scene.add_mesh_skinned(
                    f"{self.prefix}/{k}_{lk.name}",
                    vertices=geo.tube_vertices(
                        position[a : b + 1],
                        rotation[a : b + 1, :, 0],
                        rotation[a : b + 1, :, 1],
                        lk.radius_at(s[a : b + 1]),
                    ),
                    faces=geo.tube_faces(n),
                    bone_wxyzs=q[a : b + 1],
                    bone_positions=position[a : b + 1],
                    skin_weights=geo.tube_skin_weights(n),
                    color=lk.colour,
                    side="double",
                    # No shadow maps: each one is another pass over the scene per frame,
                    # which software WebGL pays for on every redraw.
                    cast_shadow=False,
                    receive_shadow=False,
                )
                continue
            for bone, w, p in zip(mesh.bones, q[a : b + 1], position[a : b + 1], strict=True):
                bone.wxyz = w
                bone.position = p
            mesh.visible = True


class Served:
    """A viser server with the page, the merged re-solves and the screenshot of a viewer.
    Subclasses set ``name`` and implement ``_solve_and_draw`` (and ``_on_close``)."""

    name = "softrod"

    def _serve(self, host: str, port: int | None, environment_map: bool) -> None:
        import viser  # optional dependency: pip install 'softrod[viewer]'

        self._run_lock = threading.Lock()
        self._pending_lock = threading.Lock()
        self._pending = False
        self._quiet = False  # set while Python moves several sliders: one solve for all
        self._closed = False
        port = free_port(host) if port is None else port
        with contextlib.redirect_stdout(io.StringIO()):  # viser's banner: we print the URL
            self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.gui.configure_theme(control_width="large")
        self.server.scene.set_up_direction("+z")
        if not environment_map:
            # Without image-based lighting the scene needs lamps: a key light from the
            # camera's side and an ambient fill.
            sc = self.server.scene
            sc.configure_environment_map(hdri=None)
            sc.add_light_directional("/lights/key", intensity=2.5, position=(1.0, -1.5, 2.0))
            sc.add_light_ambient("/lights/fill", intensity=1.2)

    @property
    def url(self) -> str:
        """Address of the page, e.g. ``http://127.0.0.1:8080``."""
        host = self.server.get_host()
        host = "127.0.0.1" if host in ("0.0.0.0", "") else host
        return f"http://{host}:{self.server.get_port()}"

    def screenshot(self, path, *, width: int = 1280, height: int = 800, timeout: float = 60.0):
        """Render the scene in a connected browser and write it as PNG (whole or not at all).
        Waits up to ``timeout`` s for a browser to connect. Returns the path."""
        from PIL import Image

        from ..io import atomic_path

        path = as_path(path)
        if path.suffix.lower() != ".png":
            raise design_error("path", str(path), "a screenshot is written as .png", InputError)
        client = self._first_client(timeout)
        image = client.get_render(
            height=height, width=width, transport_format="png", timeout=timeout
        )
        with atomic_path(path) as tmp:
            Image.fromarray(image).save(tmp, format="PNG")
        return path

    def wait(self) -> None:
        """Serve until interrupted (Ctrl-C), then close."""
        try:
            while not self._closed:
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def close(self) -> None:
        """Stop the server (the page stops updating)."""
        if not self._closed:
            self._closed = True
            self._on_close()
            self.server.stop()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _repr_html_(self) -> str:  # notebooks show the page inline
        return (
            f'<iframe src="{self.url}" width="100%" height="600" '
            'style="border:1px solid #ccc"></iframe>'
        )

    def _on_close(self) -> None:
        """What a subclass stops when the server stops (playback)."""

    def _first_client(self, timeout: float):
        deadline = time.monotonic() + timeout
        while True:
            clients = self.server.get_clients()
            if clients:
                return next(iter(clients.values()))
            if time.monotonic() > deadline:
                raise InputError(
                    f"screenshot: no browser connected to {self.url} within {timeout:g} s "
                    "(the scene is rendered by the browser: open the page first)",
                    "timeout",
                    timeout,
                    "a browser must be connected",
                )
            time.sleep(0.05)

    def _on_screenshot_button(self, event) -> None:
        path = Path.cwd() / f"softrod-{self.name}-{time.strftime('%Y%m%d-%H%M%S')}.png"
        try:
            self.screenshot(path)
            self._shot_note.content = f"wrote `{path}`"
        except Exception as exc:  # shown in the page; the server keeps running
            self._shot_note.content = f"screenshot failed: {exc}"

    def _on_slider(self, _event) -> None:
        if not self._quiet:
            self._request_solve()

    def _request_solve(self) -> None:
        """Solve for the sliders' current values; merge requests that arrive meanwhile."""
        with self._pending_lock:
            self._pending = True
        while True:
            if not self._run_lock.acquire(blocking=False):
                return  # the running solve loop picks the request up
            try:
                while True:
                    with self._pending_lock:
                        if not self._pending:
                            break
                        self._pending = False
                    self._solve_and_draw()
            finally:
                self._run_lock.release()
            with self._pending_lock:
                if not self._pending:
                    return

    def _solve_and_draw(self) -> None:
        raise NotImplementedError

    def _add_arrow(self, name: str, colour, visible: bool = True):
        """A load arrow as a skinned mesh of two bones (geometry.arrow_mesh), drawn by
        :func:`place_arrow`."""
        vertices, faces, weights = geo.arrow_mesh(**self._arrow_size)
        return self.server.scene.add_mesh_skinned(
            name,
            vertices=vertices,
            faces=faces,
            bone_wxyzs=np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0]]),
            bone_positions=np.array([[0.0, 0, 0], [0.0, 0, geo.ARROW_BIND_LENGTH]]),
            skin_weights=weights,
            color=colour,
            cast_shadow=False,
            receive_shadow=False,
            visible=visible,
        )
