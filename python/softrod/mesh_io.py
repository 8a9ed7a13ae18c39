"""Triangle-mesh files for mesh obstacles (docs/contact.md, "Triangle meshes"): STL (ASCII
and binary) and Wavefront OBJ, read with numpy alone.

:func:`read_mesh` returns the vertices (in the file's own length unit: neither format
records one, so the design states it with the obstacle's ``units`` key) and the triangles
as vertex indices. STL stores every triangle with its own three corners: corners at the
same coordinates are merged into one vertex, so that neighbouring triangles share their
edges (what the signed distance's pseudo-normals need). OBJ polygons are split into a fan
of triangles from their first corner. The winding is kept as written: counter-clockwise
seen from outside gives the outward side.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import _validate as V
from ._limits import MAX_MESH_FILE_BYTES, MAX_MESH_TRIANGLES
from .errors import DesignError, InputError, design_error
from .io import as_path

if TYPE_CHECKING:
    from numpy.typing import (
        ArrayLike,  # (not ._types: that module names Design, which reads meshes)
    )

__all__ = ["MAX_MESH_FILE_BYTES", "MAX_MESH_TRIANGLES", "read_mesh", "write_stl"]

_SUFFIXES = (".stl", ".obj")


def read_mesh(path: str | Path, field: str = "file") -> tuple[np.ndarray, np.ndarray]:
    """The vertices (float, shape (n, 3), in the file's unit) and triangles (int, shape
    (m, 3)) of an STL or OBJ file; :class:`DesignError` naming ``field`` for a missing,
    unreadable, oversized or malformed file."""
    if not (isinstance(field, str) and field.strip()):
        raise design_error(
            "field", type(field).__name__, "must be text: the name errors give the file", InputError
        )
    path = as_path(path, field)
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise design_error(
            field, str(path), "must be an STL (.stl) or Wavefront OBJ (.obj) triangle mesh file"
        )
    try:
        size = path.stat().st_size
        if size > MAX_MESH_FILE_BYTES:
            raise design_error(
                field,
                f"{size} bytes",
                f"is too large for a mesh file ({MAX_MESH_FILE_BYTES} bytes at most; decimate "
                "the mesh)",
            )
        data = path.read_bytes()
    except FileNotFoundError:
        raise design_error(
            field,
            str(path),
            "no such file (a relative path is relative to the design file's folder)",
        ) from None
    except OSError as exc:
        rule = f"cannot read the mesh file: {exc.strerror or exc}"
        raise design_error(field, str(path), rule) from None
    if suffix == ".obj":
        vertices, faces = _obj(data, field)
    else:
        vertices, faces = _stl(data, field)
    if len(faces) == 0:
        raise design_error(field, str(path), "has no triangles")
    return vertices, faces


def _too_many(field: str, n: int) -> DesignError:
    return design_error(
        field,
        f"{n} triangles",
        f"a mesh obstacle may have at most {MAX_MESH_TRIANGLES} triangles (decimate it)",
    )


def _stl(data: bytes, field: str) -> tuple[np.ndarray, np.ndarray]:
    """Binary when the size matches the header's triangle count (84 + 50 n bytes; a binary
    header may itself begin with "solid"), else ASCII."""
    if len(data) >= 84:
        (n,) = struct.unpack_from("<I", data, 80)
        if len(data) == 84 + 50 * n:
            if n > MAX_MESH_TRIANGLES:
                raise _too_many(field, n)
            rec = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
            corners = np.frombuffer(data, dtype=rec, count=n, offset=84)["corners"]
            return _weld(corners.astype(float).reshape(-1, 3), field)
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        raise design_error(
            field,
            f"{len(data)} bytes",
            "is not a valid STL file: neither binary (84 + 50 n bytes for n triangles) nor "
            "ASCII text",
        ) from None
    tokens = text.split()
    if not tokens or tokens[0].lower() != "solid":
        raise design_error(
            field, tokens[0] if tokens else "", "an ASCII STL must begin with 'solid'"
        )
    lowered = [t.lower() for t in tokens]
    corners: list[list[float]] = []
    for i, t in enumerate(lowered):
        if t != "vertex":
            continue
        try:
            corners.append([float(x) for x in tokens[i + 1 : i + 4]])
        except ValueError:
            raise design_error(
                field,
                " ".join(tokens[i : i + 4]),
                "is not a valid STL vertex line ('vertex x y z' with three numbers)",
            ) from None
        if len(corners[-1]) != 3:
            raise design_error(field, "vertex", "an STL vertex line needs three numbers")
        if len(corners) > 3 * MAX_MESH_TRIANGLES:
            raise _too_many(field, len(corners) // 3)
    facets = lowered.count("facet")
    if len(corners) != 3 * facets or lowered.count("endfacet") != facets:
        raise design_error(
            field,
            f"{facets} facets, {len(corners)} vertices",
            "is not a valid ASCII STL: every 'facet' ... 'endfacet' must hold exactly three "
            "'vertex' lines",
        )
    return _weld(np.array(corners, dtype=float).reshape(-1, 3), field)


def _weld(corners: np.ndarray, field: str) -> tuple[np.ndarray, np.ndarray]:
    """Corners at identical coordinates as one vertex (STL repeats them per triangle)."""
    if not np.all(np.isfinite(corners)):
        i = int(np.argwhere(~np.isfinite(corners))[0][0])
        raise design_error(
            field, str(corners[i].tolist()), f"triangle {i // 3} has a non-finite coordinate"
        )
    vertices, inverse = np.unique(corners, axis=0, return_inverse=True)
    return vertices, np.asarray(inverse, dtype=np.int64).reshape(-1, 3)


def _obj(data: bytes, field: str) -> tuple[np.ndarray, np.ndarray]:
    """``v x y z`` vertices and ``f`` polygons (``i``, ``i/t``, ``i//n``, ``i/t/n``; 1-based,
    negative counts back from the last vertex), fan-triangulated; other lines ignored."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise design_error(
            field, f"{len(data)} bytes", "is not a valid OBJ file (not text)"
        ) from None
    vertices: list[list[float]] = []
    faces: list[list[int]] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        if parts[0] == "v":
            try:
                xyz = [float(x) for x in parts[1:4]]
            except ValueError:
                xyz = []
            if len(xyz) != 3:
                raise design_error(
                    field, line.strip(), f"line {lineno}: a vertex reads 'v x y z' (three numbers)"
                )
            vertices.append(xyz)
        elif parts[0] == "f":
            idx = []
            for p in parts[1:]:
                try:
                    i = int(p.split("/", 1)[0])
                except ValueError:
                    i = 0
                n = len(vertices)
                k = i - 1 if i > 0 else n + i
                if i == 0 or not 0 <= k < n:
                    raise design_error(
                        field,
                        line.strip(),
                        f"line {lineno}: face corner {p!r} must index one of the {n} vertices "
                        "read so far (1-based, or negative from the last)",
                    )
                idx.append(k)
            if len(idx) < 3:
                raise design_error(
                    field, line.strip(), f"line {lineno}: a face needs at least three corners"
                )
            faces.extend([idx[0], idx[j], idx[j + 1]] for j in range(1, len(idx) - 1))
            if len(faces) > MAX_MESH_TRIANGLES:
                raise _too_many(field, len(faces))
    v = np.array(vertices, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(v)):
        i = int(np.argwhere(~np.isfinite(v))[0][0])
        raise design_error(field, str(v[i].tolist()), f"vertex {i + 1} has a non-finite coordinate")
    return v, np.array(faces, dtype=np.int64).reshape(-1, 3)


MAX_COORDINATE = 1e15


def write_stl(
    path: str | Path, vertices: ArrayLike, faces: ArrayLike, *, binary: bool = True
) -> Path:
    """Write triangles (``vertices`` (n, 3), ``faces`` (m, 3) indices) as an STL file
    (binary or ASCII), whole or not at all; returns the path."""
    from .io import atomic_path

    v = V.real_array(vertices, "vertices", what="coordinates")
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
        raise design_error(
            "vertices", f"shape {v.shape}", "must be (n, 3) coordinates, n >= 3", InputError
        )
    # STL stores 32-bit floats; 1e15 (in any unit) is beyond every mesh and keeps the
    # normals' products far inside them.
    if np.abs(v).max() > MAX_COORDINATE:
        raise design_error(
            "vertices", float(np.abs(v).max()), f"must be within +-{MAX_COORDINATE:g}", InputError
        )
    raw = V.real_array(faces, "faces", what="vertex indices")
    if raw.ndim != 2 or raw.shape[1] != 3 or len(raw) < 1:
        raise design_error(
            "faces", f"shape {raw.shape}", "must be (m, 3) indices, m >= 1", InputError
        )
    bad = np.flatnonzero((raw != np.round(raw)) | (raw < 0) | (raw >= len(v)))
    if bad.size:
        i = int(bad[0])
        raise design_error(
            f"faces[{i // 3}][{i % 3}]",
            raw.flat[i],
            f"must be a whole index of a vertex, 0 <= i < {len(v)}",
            InputError,
        )
    f = raw.astype(np.int64)
    path = as_path(path)
    tri = v[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    if binary:
        rec = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
        out = np.zeros(len(f), dtype=rec)
        out["normal"] = normal
        out["corners"] = tri
        payload = b"softrod mesh".ljust(80, b" ") + struct.pack("<I", len(f)) + out.tobytes()
    else:
        lines = ["solid softrod"]
        for n, t in zip(normal.tolist(), tri.tolist(), strict=True):
            lines.append(f"  facet normal {n[0]!r} {n[1]!r} {n[2]!r}")
            lines.append("    outer loop")
            lines.extend(f"      vertex {p[0]!r} {p[1]!r} {p[2]!r}" for p in t)
            lines.append("    endloop")
            lines.append("  endfacet")
        lines.append("endsolid softrod")
        payload = ("\n".join(lines) + "\n").encode("ascii")
    with atomic_path(path) as tmp:
        tmp.write_bytes(payload)
    return path
