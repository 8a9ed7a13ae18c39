"""What the viewer draws, as plain numpy (no viser here, so it is testable on its own):
the rod's sections with their kind, colour and outer radius, the tube mesh around a
solved centreline, quaternions of frames, load arrows and the chamber cross-section (SVG).

Everything is vectorised over the nodes: one mesh for a whole section is a handful of array
operations on the (n, 3) centreline and the (n, 3, 3) rotations that the Rust solve returns.
Lengths are metres (the scene's unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..design import Design

#: Points around the tube's circumference (smooth enough at the sizes drawn, ~1 ms to mesh).
RING = 32

#: Section colours (RGB): caps and other plain elastic parts, the chambered body, rigid parts.
COLOURS = {
    "cap": (150, 170, 190),
    "chambered": (240, 150, 60),
    "rigid": (90, 90, 100),
}

#: Wall outside the chambers when a design gives no outer radius (the drawn tube encloses
#: the chambers with this relative margin; the panel says the radius is not the design's).
ENVELOPE_MARGIN = 1.15


@dataclass(frozen=True)
class SectionLook:
    """How one section is drawn: kind ("cap", "chambered", "rigid"), colour, outer radius
    (m) at its start and its end (a tapered section: linear in s between them) and whether
    that radius is the design's own (False: drawn from the chambers or a neighbour, because
    the design gives none)."""

    name: str
    kind: str
    colour: tuple[int, int, int]
    radius: float
    radius_from_design: bool
    s0: float
    s1: float
    radius_end: float | None = None  # None: the section is not tapered

    def radius_at(self, s) -> np.ndarray:
        """Outer radius (m) at arc lengths ``s``: linear from ``radius`` at s0 to
        ``radius_end`` at s1 (the design's taper, docs/design-format.md), clamped."""
        s = np.asarray(s, dtype=float)
        if self.radius_end is None or self.s1 <= self.s0:
            return np.full(s.shape, self.radius)
        u = np.clip((s - self.s0) / (self.s1 - self.s0), 0.0, 1.0)
        return self.radius + u * (self.radius_end - self.radius)


def section_looks(design: Design) -> list[SectionLook]:
    """Kind, colour, radius and arc-length span of every section of ``design``."""
    secs = design.spec["sections"]
    radii: list[float | None] = []
    ends: list[float | None] = []  # at the section's end, where it tapers
    own: list[bool] = []
    for sec in secs:
        if sec.get("outer_radius"):
            radii.append(float(sec["outer_radius"]))
            ends.append(float(sec["outer_radius_end"]) if "outer_radius_end" in sec else None)
            own.append(True)
        elif sec["chambers"]:
            cs = sec["chambers"]

            def reach(c, end=False):
                r = c["radius"] or math.sqrt(c["area"] / math.pi)
                if end:
                    return c.get("distance_end", c["distance"]) + c.get("radius_end", r)
                return c["distance"] + r

            radii.append(ENVELOPE_MARGIN * max(reach(c) for c in cs))
            tapered = any("distance_end" in c or "radius_end" in c for c in cs)
            ends.append(ENVELOPE_MARGIN * max(reach(c, True) for c in cs) if tapered else None)
            own.append(False)
        else:
            radii.append(None)
            ends.append(None)
            own.append(False)
    known = [i for i, r in enumerate(radii) if r is not None]
    fallback = design.length / 20.0  # no section says anything about its size
    looks, s = [], 0.0
    for i, sec in enumerate(secs):
        r, r_end = radii[i], ends[i]
        if r is None:
            r = radii[min(known, key=lambda k: abs(k - i))] if known else fallback
        kind = "rigid" if sec["rigid"] else ("chambered" if sec["chambers"] else "cap")
        looks.append(
            SectionLook(
                sec["name"], kind, COLOURS[kind], float(r), own[i], s, s + sec["length"], r_end
            )
        )
        s += sec["length"]
    return looks


def section_of_arclength(looks: list[SectionLook], s: np.ndarray) -> np.ndarray:
    """Section index of every arc length (a node on a junction belongs to the later one)."""
    ends = np.array([lk.s1 for lk in looks[:-1]])
    return np.searchsorted(ends, np.asarray(s), side="right")


def node_ranges(section: np.ndarray, n_sections: int) -> list[tuple[int, int] | None]:
    """For each section, the (first, last) node indices that its tube spans, inclusive; the
    next section's first node is added so that neighbouring tubes meet without a gap."""
    out: list[tuple[int, int] | None] = []
    n = section.size
    for k in range(n_sections):
        idx = np.flatnonzero(section == k)
        if idx.size == 0:
            out.append(None)
            continue
        a, b = int(idx[0]), int(idx[-1])
        out.append((a, min(b + 1, n - 1) if b + 1 < n and section[b + 1] != k else b))
    return out


def tube_faces(n: int, ring: int = RING) -> np.ndarray:
    """Triangles (uint32) of a tube of ``n`` rings of ``ring`` points, closed at both ends
    by fans around a centre vertex (vertex n * ring is the start centre, n * ring + 1 the end
    centre)."""
    i = np.arange(n - 1)[:, None]
    k = np.arange(ring)[None, :]
    a = i * ring + k
    b = i * ring + (k + 1) % ring
    c = a + ring
    d = b + ring
    side = np.concatenate(
        [np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)]
    )
    k = np.arange(ring)
    start = np.stack([np.full(ring, n * ring), (k + 1) % ring, k], -1)
    last = (n - 1) * ring
    end = np.stack([np.full(ring, n * ring + 1), last + k, last + (k + 1) % ring], -1)
    return np.concatenate([side, start, end]).astype(np.uint32)


def tube_vertices(
    position: np.ndarray, d1: np.ndarray, d2: np.ndarray, radius, ring: int = RING
) -> np.ndarray:
    """Vertices (n * ring + 2, 3) of a tube: at node i the circle of ``radius`` in the plane
    of (d1_i, d2_i) around position_i, then the two end centres (see :func:`tube_faces`)."""
    theta = 2.0 * np.pi * np.arange(ring) / ring
    r = np.broadcast_to(np.asarray(radius, dtype=float), position.shape[:1])[:, None, None]
    cos, sin = np.cos(theta)[None, :, None], np.sin(theta)[None, :, None]
    circle = cos * d1[:, None, :] + sin * d2[:, None, :]
    rings = position[:, None, :] + r * circle
    return np.concatenate([rings.reshape(-1, 3), position[:1], position[-1:]]).astype(np.float32)


def transport_frames(position: np.ndarray, base_rotation: np.ndarray) -> np.ndarray:
    """Rotations (n, 3, 3) along a centreline that stores no frames (a Trajectory's shapes):
    d3 is the unit tangent and (d1, d2) the base's, turned by the smallest rotation that takes
    the base tangent to each node's tangent. The tube is round, so only the tangent matters
    for its surface; this is exact for it up to bends of nearly 180 deg from the base tangent,
    where the smallest rotation is not unique (the normal plane is still right there)."""
    t = np.gradient(position, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    t0 = base_rotation[:, 2]
    axis = np.cross(t0, t)
    c = t @ t0
    # Rodrigues for the rotation t0 -> t: R = I + [a]x + [a]x^2 / (1 + c).
    ax = np.zeros((t.shape[0], 3, 3))
    ax[:, 0, 1], ax[:, 0, 2], ax[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    ax -= np.transpose(ax, (0, 2, 1))
    turn = np.eye(3) + ax + (ax @ ax) / np.maximum(1.0 + c, 1e-9)[:, None, None]
    return turn @ base_rotation


def wxyz(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z), shape (..., 4), of rotation matrices (..., 3, 3), by
    Shepperd's method: from the largest of 1 + trace and the 1 + 2 m_ii - trace, so that
    no division is by a small number."""
    m = np.asarray(rotation, dtype=float)
    tr = np.trace(m, axis1=-2, axis2=-1)
    diag = np.diagonal(m, axis1=-2, axis2=-1)
    # 4 q_k^2 for k = w, x, y, z: 1 + tr, and 1 + 2 m_ii - tr.
    big = np.concatenate([(1.0 + tr)[..., None], 1.0 + 2.0 * diag - tr[..., None]], axis=-1)
    k = np.argmax(big, axis=-1)
    s = 2.0 * np.sqrt(np.maximum(np.take_along_axis(big, k[..., None], -1)[..., 0], 1e-300))
    # Sums and differences of off-diagonal pairs: 4 q_a q_b for each pair (a, b).
    wx, wy, wz = (
        m[..., 2, 1] - m[..., 1, 2],
        m[..., 0, 2] - m[..., 2, 0],
        m[..., 1, 0] - m[..., 0, 1],
    )
    xy, xz, yz = (
        m[..., 0, 1] + m[..., 1, 0],
        m[..., 0, 2] + m[..., 2, 0],
        m[..., 1, 2] + m[..., 2, 1],
    )
    quarter = 0.25 * s
    rows = [
        [quarter, wx / s, wy / s, wz / s],  # from w
        [wx / s, quarter, xy / s, xz / s],  # from x
        [wy / s, xy / s, quarter, yz / s],  # from y
        [wz / s, xz / s, yz / s, quarter],  # from z
    ]
    q = np.zeros(m.shape[:-2] + (4,))
    for j, row in enumerate(rows):
        q = np.where((k == j)[..., None], np.stack(row, axis=-1), q)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def tube_skin_weights(n: int, ring: int = RING) -> np.ndarray:
    """Skin weights (n * ring + 2, n) of :func:`tube_vertices`' tube on one bone per node:
    every ring, and each end centre, rides rigidly on its node's frame, so posing bone i
    at node i's position and rotation redraws the tube of the new shape exactly (the
    ring's points are fixed in the node's cross-section frame)."""
    w = np.zeros((n * ring + 2, n), dtype=np.float32)
    w[np.arange(n * ring), np.repeat(np.arange(n), ring)] = 1.0
    w[n * ring, 0] = w[n * ring + 1, n - 1] = 1.0
    return w


def frame_along(direction) -> np.ndarray:
    """A rotation whose third column is the unit ``direction`` (viser's cylinders and the
    plane's slab have their axis along the local z)."""
    z = np.asarray(direction, dtype=float)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


#: Most triangles of a mesh obstacle the viewer and the plots draw: a bigger mesh is drawn
#: by an evenly spread subset of its triangles (every k-th), which keeps the browser and
#: matplotlib responsive; the contact always uses the whole mesh.
MAX_DRAWN_TRIANGLES = 20_000


def drawn_triangles(obstacle: dict, limit: int = MAX_DRAWN_TRIANGLES) -> np.ndarray:
    """A mesh obstacle's triangles to draw, as corners (m, 3, 3) in metres: all of them, or
    every k-th when there are more than ``limit``."""
    v = np.asarray(obstacle["vertices"], dtype=float)
    f = np.asarray(obstacle["faces"], dtype=np.int64)
    stride = max(1, -(-len(f) // limit))
    return v[f[::stride]]


def obstacle_solids(obstacle: dict, centre, size: float) -> list[tuple[str, dict]]:
    """The solids that draw one obstacle of a design (its spec: SI, docs/contact.md), as
    (kind, arguments) with kind "box", "sphere", "cylinder" or "mesh": a plane is a square
    slab of side ``2 size`` below its surface centred under ``centre`` (the rod's middle),
    an infinite cylinder a cylinder of length ``3 size`` centred at ``centre``'s foot on its
    axis, a capsule its segment's cylinder and the two end balls, a mesh its triangles
    (:func:`drawn_triangles`: at most MAX_DRAWN_TRIANGLES)."""
    kind = obstacle["kind"]
    if kind == "mesh":
        tri = drawn_triangles(obstacle)
        faces = np.arange(3 * len(tri), dtype=np.uint32).reshape(-1, 3)
        return [("mesh", {"vertices": tri.reshape(-1, 3).astype(np.float32), "faces": faces})]
    if kind == "plane":
        n = np.asarray(obstacle["normal"], float)
        n /= np.linalg.norm(n)
        p = np.asarray(obstacle["point"], float)
        c = np.asarray(centre, float)
        foot = c - np.dot(c - p, n) * n
        thick = 0.02 * size
        rot = frame_along(n)
        box = {"dimensions": (2 * size, 2 * size, thick), "position": foot - 0.5 * thick * n}
        return [("box", {**box, "wxyz": wxyz(rot)})]
    if kind == "sphere":
        return [("sphere", {"radius": obstacle["radius"], "position": obstacle["center"]})]
    if kind == "cylinder":
        a = np.asarray(obstacle["axis"], float)
        a /= np.linalg.norm(a)
        p = np.asarray(obstacle["point"], float)
        foot = p + np.dot(np.asarray(centre, float) - p, a) * a
        rot = frame_along(a)
        args = {"radius": obstacle["radius"], "height": 3 * size, "position": foot}
        return [("cylinder", {**args, "wxyz": wxyz(rot)})]
    if kind == "capsule":
        a, b = (np.asarray(obstacle[k], float) for k in ("start", "end"))
        r = obstacle["radius"]
        rot = frame_along(b - a)
        body = {"radius": r, "height": float(np.linalg.norm(b - a)), "position": 0.5 * (a + b)}
        return [
            ("cylinder", {**body, "wxyz": wxyz(rot)}),
            ("sphere", {"radius": r, "position": a}),
            ("sphere", {"radius": r, "position": b}),
        ]
    raise ValueError(f"unknown obstacle kind {kind!r}")


def arrow(start, vector) -> np.ndarray:
    """One arrow as viser's (1, 2, 3) start/end points."""
    start = np.asarray(start, dtype=float)
    return np.stack([start, start + np.asarray(vector, dtype=float)])[None]


#: Bind length (m) of :func:`arrow_mesh`'s arrow; any length is drawn by posing its bones.
ARROW_BIND_LENGTH = 1.0
#: Points around :func:`arrow_mesh`'s shaft and head.
ARROW_RING = 16


def arrow_mesh(
    shaft_radius: float, head_radius: float, head_length: float, ring: int = ARROW_RING
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An arrow along +z as a skinned mesh of two bones: (vertices, faces, skin weights).
    Bone 0 sits at the arrow's start, bone 1 at its end (bind pose: the origin and
    (0, 0, ARROW_BIND_LENGTH), both unrotated). The shaft's foot rides on bone 0; its top
    ring, the head's base and the apex ride on bone 1, a fixed head_length behind the end:
    posing bone 0 at the start and bone 1 at start + vector, both turned from z to the
    vector, draws an arrow of any length and direction with a head of fixed size."""
    theta = 2.0 * np.pi * np.arange(ring) / ring
    circle = np.stack([np.cos(theta), np.sin(theta), np.zeros(ring)], axis=1)
    top = ARROW_BIND_LENGTH - head_length
    z = np.array([0.0, 0.0, 1.0])
    verts = np.concatenate(
        [
            shaft_radius * circle,  # 0: shaft foot (bone 0)
            shaft_radius * circle + top * z,  # ring: shaft top (bone 1)
            head_radius * circle + top * z,  # 2 ring: head base (bone 1)
            [np.zeros(3), top * z, ARROW_BIND_LENGTH * z],  # foot centre, base centre, apex
        ]
    )
    k = np.arange(ring)
    nxt = (k + 1) % ring
    foot, base, apex = 3 * ring, 3 * ring + 1, 3 * ring + 2
    faces = np.concatenate(
        [
            np.stack([k, nxt, ring + nxt], -1),  # shaft side
            np.stack([k, ring + nxt, ring + k], -1),
            np.stack([np.full(ring, foot), nxt, k], -1),  # foot disc
            np.stack([np.full(ring, base), 2 * ring + k, 2 * ring + nxt], -1),  # head base
            np.stack([np.full(ring, apex), 2 * ring + nxt, 2 * ring + k], -1),  # cone
        ]
    ).astype(np.uint32)
    weights = np.zeros((verts.shape[0], 2), np.float32)
    weights[:ring, 0] = weights[foot, 0] = 1.0
    weights[ring : 3 * ring, 1] = weights[base, 1] = weights[apex, 1] = 1.0
    return verts.astype(np.float32), faces, weights


def cross_section_svg(
    section: dict,
    pressures: np.ndarray,
    p_max: float,
    radius: float,
    size: int = 150,
    tensions: np.ndarray | None = None,
    t_max: float = 1.0,
) -> str:
    """The cross-section seen from the tip towards the base (d1 to the right, d2 up): outer
    disc, bore and chambers, each chamber filled by its channel's pressure (white 0 to
    orange at ``p_max``) and labelled with its channel; each tendon a small disc where its
    route starts in the section, filled by its tension (white 0 to blue at ``t_max``) and
    labelled t and its channel."""
    # The disc leaves a margin for the axis labels outside it (no label over a tendon on
    # the rim).
    scale = 0.40 * size / radius
    cx = cy = size / 2

    def xy(r, angle):
        return cx + scale * r * math.cos(angle), cy - scale * r * math.sin(angle)

    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" '
        f'viewBox="0 0 {size} {size}">',
        f'<circle cx="{cx}" cy="{cy}" r="{scale * radius:.2f}" fill="#f0d8c0" stroke="#555"/>',
    ]
    if section.get("bore_radius"):
        r = scale * section["bore_radius"]
        parts.append(f'<circle cx="{cx}" cy="{cy}" r="{r:.2f}" fill="#fff" stroke="#555"/>')
    for ch in section["chambers"]:
        rc = ch["radius"] or math.sqrt(ch["area"] / math.pi)
        x, y = xy(ch["distance"], ch["angle"])
        p = float(pressures[ch["channel"]]) if ch["channel"] < len(pressures) else 0.0
        f = min(max(p / p_max, 0.0), 1.0) if p_max > 0 else 0.0
        fill = f"#ff{int(255 - 105 * f):02x}{int(255 - 195 * f):02x}"
        parts.append(
            f'<circle cx="{x:.2f}" cy="{y:.2f}" r="{scale * rc:.2f}" fill="{fill}" '
            f'stroke="#333"/><text x="{x:.2f}" y="{y + 4:.2f}" font-size="11" '
            f'text-anchor="middle" font-family="sans-serif">{ch["channel"]}</text>'
        )
    for td in section.get("tendons", []):
        x, y = xy(td["distance"], td["angle"])
        k = td["channel"]
        t = float(tensions[k]) if tensions is not None and k < len(tensions) else 0.0
        f = min(max(t / t_max, 0.0), 1.0) if t_max > 0 else 0.0
        fill = f"#{int(255 - 225 * f):02x}{int(255 - 155 * f):02x}ff"
        # The label beside the disc, a quarter turn on (counter-clockwise along the rim): off
        # the radial line where the chambers and the axis labels are.
        lx, ly = x - 10 * math.sin(td["angle"]), y - 10 * math.cos(td["angle"])
        parts.append(
            f'<circle cx="{x:.2f}" cy="{y:.2f}" r="4" fill="{fill}" stroke="#1f3c88"/>'
            f'<text x="{lx:.2f}" y="{ly + 3:.2f}" font-size="9" text-anchor="middle" '
            f'font-family="sans-serif" fill="#1f3c88">t{k}</text>'
        )
    parts.append(
        f'<text x="{size - 2}" y="{cy + 14}" font-size="9" text-anchor="end" '
        f'font-family="sans-serif" fill="#555">d1</text>'
        f'<text x="{cx + 14}" y="8" font-size="9" font-family="sans-serif" fill="#555">d2</text>'
        "</svg>"
    )
    return "".join(parts)
