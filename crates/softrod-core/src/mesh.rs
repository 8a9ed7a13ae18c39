//! Rigid triangle meshes for contact (`kind = "mesh"`, docs/contact.md, "Triangle meshes").
//!
//! A mesh is a list of vertices and of triangles (vertex indices) whose winding gives the
//! outward side: counter-clockwise seen from outside, so the face normal
//! (b - a) x (c - a) points out. Closed or open: a closed mesh's inside is penetration; an
//! open one (a terrain patch) has its inside on the side opposite its normals.
//!
//! The signed distance of a point p is found in two steps. First, in f64, the nearest point
//! q of the mesh and the feature it lies on (a face's interior, an edge, a vertex), by a
//! bounding-volume hierarchy of axis-aligned boxes (`Bvh`: O(log n) per query for a
//! well-spread mesh). The sign is that of (p - q) . n_f with n_f the feature's
//! angle-weighted pseudo-normal (Baerentzen and Aanaes, "Signed distance computation using
//! the angle weighted pseudonormal", IEEE TVCG 11(3):243-253, 2005,
//! DOI 10.1109/TVCG.2005.49): the face normal on a face, the sum of the two faces' normals
//! on an edge, the sum of the incident faces' normals weighted by their angles at a vertex.
//! For a closed, consistently oriented mesh that sign is exact everywhere. An open mesh
//! (a terrain patch, a table top) is one-sided: a point nearest to its border (an edge of
//! one face only, or an end of one) is outside, at its distance from the border, as from
//! the edge of a thin sheet; a point nearest to the inner faces, edges or vertices takes
//! the pseudo-normal's sign, so the region under the patch (opposite its normals, within
//! its border) is inside. Second, generic
//! in the scalar, the distance to that feature alone: to the face's plane (linear in p), to
//! the edge's line (as a cylinder of radius 0), to the vertex (as a sphere of radius 0).
//! Each is the exact signed distance wherever the feature stays the nearest one, so its
//! dual-number derivatives are exact; across the border of two features' regions value and
//! gradient agree (both are |p - q| along the same direction), so the distance is C1
//! outside the mesh and inside it away from its medial axis, as for the other shapes.

use crate::error::{Result, SoftrodError};
use crate::jet::RodScalar;
use std::collections::HashMap;

/// Most triangles a mesh obstacle may have.
pub const MAX_MESH_TRIANGLES: usize = 200_000;

/// Most vertices a mesh obstacle may have (three per triangle: an unwelded soup).
pub const MAX_MESH_VERTICES: usize = 3 * MAX_MESH_TRIANGLES;

/// Largest |coordinate| of a mesh vertex, m: a kilometre is far beyond any actuator's
/// workspace, and products of coordinates stay far from overflow.
pub const MAX_MESH_COORDINATE: f64 = 1e3;

/// A triangle whose area is below this fraction of its longest edge squared is refused as
/// degenerate (its normal is not defined to working precision).
const DEGENERATE_AREA: f64 = 1e-12;

/// Where on a mesh a nearest point lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feature {
    /// The interior of face f.
    Face(usize),
    /// Edge e (`TriMesh::edges`), between its ends.
    Edge(usize),
    /// Vertex v.
    Vertex(usize),
}

/// The nearest point of a mesh to a point p: where it is, its feature and |p - q|^2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    pub point: [f64; 3],
    pub feature: Feature,
    pub dist2: f64,
}

/// A node of the hierarchy: a box and either two children (`count == 0`: the left one
/// follows this node, the right one is at `index`) or triangles `order[index..index +
/// count]`.
#[derive(Debug, Clone, PartialEq)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    index: u32,
    count: u32,
}

/// Triangles per leaf of the hierarchy.
const LEAF: usize = 4;

/// A compiled, validated triangle mesh: geometry, pseudo-normals and the hierarchy.
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<[f64; 3]>,
    pub faces: Vec<[usize; 3]>,
    /// Unit outward normal of each face.
    pub face_normals: Vec<[f64; 3]>,
    /// Undirected edges (lower index first) and each face's three: edge k of a face joins
    /// its corners k and k + 1 (mod 3).
    pub edges: Vec<[usize; 2]>,
    face_edges: Vec<[usize; 3]>,
    /// Unit pseudo-normals of the edges and vertices (vertices on no face: zero).
    edge_normals: Vec<[f64; 3]>,
    vertex_normals: Vec<[f64; 3]>,
    /// Edges on one face only, and their ends: an open mesh's border.
    border_edge: Vec<bool>,
    border_vertex: Vec<bool>,
    closed: bool,
    /// The faces on each edge (the second `usize::MAX` on a border), and the faces
    /// around each vertex: `vertex_faces[vertex_start[v]..vertex_start[v + 1]]`.
    edge_faces: Vec<[usize; 2]>,
    vertex_start: Vec<usize>,
    vertex_faces: Vec<usize>,
    /// Whether a face has a concave neighbour around its corners (`concave`): only those
    /// blend (`blend_creases`).
    creased: Vec<bool>,
    nodes: Vec<Node>,
    order: Vec<u32>,
}

fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: &[f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// The angle between a and b (both non-zero), robust near 0 and pi.
fn angle(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    norm(&cross(a, b)).atan2(dot(a, b))
}

/// Check the vertices and faces of mesh obstacle `k` (`field` is "obstacles[k]"): sizes,
/// finite coordinates within `MAX_MESH_COORDINATE`, indices in range, no degenerate
/// triangle. The mesh's topology (edges shared consistently) is [`TriMesh::new`]'s.
pub fn check(field: &str, vertices: &[[f64; 3]], faces: &[[usize; 3]]) -> Result<()> {
    if faces.is_empty() {
        return Err(SoftrodError::invalid(
            format!("{field}.faces"),
            "[]",
            "must list at least one triangle",
        ));
    }
    if faces.len() > MAX_MESH_TRIANGLES {
        return Err(SoftrodError::invalid(
            format!("{field}.faces"),
            format!("{} triangles", faces.len()),
            format!(
                "a mesh obstacle may have at most {MAX_MESH_TRIANGLES} triangles (decimate it)"
            ),
        ));
    }
    if vertices.len() > MAX_MESH_VERTICES {
        return Err(SoftrodError::invalid(
            format!("{field}.vertices"),
            format!("{} vertices", vertices.len()),
            format!("a mesh obstacle may have at most {MAX_MESH_VERTICES} vertices"),
        ));
    }
    for (i, v) in vertices.iter().enumerate() {
        for (j, x) in v.iter().enumerate() {
            if !(x.is_finite() && x.abs() <= MAX_MESH_COORDINATE) {
                return Err(SoftrodError::invalid(
                    format!("{field}.vertices[{i}][{j}]"),
                    x,
                    format!(
                        "must be a finite coordinate within {MAX_MESH_COORDINATE} m of the origin"
                    ),
                ));
            }
        }
    }
    for (f, t) in faces.iter().enumerate() {
        for (j, &i) in t.iter().enumerate() {
            if i >= vertices.len() {
                return Err(SoftrodError::invalid(
                    format!("{field}.faces[{f}][{j}]"),
                    i,
                    format!(
                        "must index one of the {} vertices (0 to {})",
                        vertices.len(),
                        vertices.len().saturating_sub(1)
                    ),
                ));
            }
        }
        let [a, b, c] = t.map(|i| vertices[i]);
        let (ab, ac, bc) = (sub(&b, &a), sub(&c, &a), sub(&c, &b));
        let longest = dot(&ab, &ab).max(dot(&ac, &ac)).max(dot(&bc, &bc));
        let twice_area = norm(&cross(&ab, &ac));
        if twice_area.is_nan() || twice_area <= DEGENERATE_AREA * longest {
            return Err(SoftrodError::invalid(
                format!("{field}.faces[{f}]"),
                format!("{t:?}"),
                format!(
                    "is a degenerate triangle (area {:.3e} m^2, below {DEGENERATE_AREA:e} of its longest edge squared: repeated or collinear vertices); remove it",
                    0.5 * twice_area
                ),
            ));
        }
    }
    Ok(())
}

impl TriMesh {
    /// Compile mesh obstacle `field` ("obstacles[k]"): [`check`], then the edges (each
    /// shared by at most two faces, in opposite directions: a consistent winding), the
    /// pseudo-normals (none that cancels) and the hierarchy.
    pub fn new(field: &str, vertices: &[[f64; 3]], faces: &[[usize; 3]]) -> Result<TriMesh> {
        check(field, vertices, faces)?;
        let face_normals: Vec<[f64; 3]> = faces
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i]);
                let n = cross(&sub(&b, &a), &sub(&c, &a));
                let l = norm(&n);
                n.map(|x| x / l)
            })
            .collect();
        // Edges: (low, high) -> (id, the first face and whether it runs low -> high).
        let mut ids: HashMap<[usize; 2], (usize, usize, bool)> =
            HashMap::with_capacity(faces.len() * 3 / 2 + 1);
        let mut edges = Vec::with_capacity(faces.len() * 3 / 2 + 1);
        let mut uses: Vec<u8> = Vec::with_capacity(faces.len() * 3 / 2 + 1);
        let mut face_edges = Vec::with_capacity(faces.len());
        for (f, t) in faces.iter().enumerate() {
            let mut fe = [0; 3];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = [a.min(b), a.max(b)];
                let forward = a < b;
                let e = match ids.get(&key) {
                    None => {
                        ids.insert(key, (edges.len(), f, forward));
                        edges.push(key);
                        uses.push(1);
                        edges.len() - 1
                    }
                    Some(&(e, g, dir)) => {
                        if uses[e] >= 2 {
                            return Err(SoftrodError::invalid(
                                format!("{field}.faces[{f}]"),
                                format!("{t:?}"),
                                format!(
                                    "shares the edge ({}, {}) with two other faces (faces[{g}] among them): a mesh whose edge joins three or more triangles has no inside; give each closed or open surface as its own obstacle",
                                    key[0], key[1]
                                ),
                            ));
                        }
                        if dir == forward {
                            return Err(SoftrodError::invalid(
                                format!("{field}.faces[{f}]"),
                                format!("{t:?}"),
                                format!(
                                    "runs along the edge ({a}, {b}) in the same direction as faces[{g}]: the faces' winding must be consistent (counter-clockwise seen from outside, so each shared edge runs both ways); flip one of them"
                                ),
                            ));
                        }
                        uses[e] += 1;
                        e
                    }
                };
                fe[k] = e;
            }
            face_edges.push(fe);
        }
        let mut edge_sum = vec![[0.0; 3]; edges.len()];
        let mut vertex_sum = vec![[0.0; 3]; vertices.len()];
        for (f, t) in faces.iter().enumerate() {
            let n = face_normals[f];
            for k in 0..3 {
                let e = &mut edge_sum[face_edges[f][k]];
                for i in 0..3 {
                    e[i] += n[i];
                }
                let p = vertices[t[k]];
                let w = angle(
                    &sub(&vertices[t[(k + 1) % 3]], &p),
                    &sub(&vertices[t[(k + 2) % 3]], &p),
                );
                let v = &mut vertex_sum[t[k]];
                for i in 0..3 {
                    v[i] += w * n[i];
                }
            }
        }
        let mut edge_normals = Vec::with_capacity(edges.len());
        for (e, s) in edge_sum.iter().enumerate() {
            let l = norm(s);
            // Two faces folded flat onto each other (a 360 degree dihedral) cancel.
            if l.is_nan() || l <= 1e-9 {
                let [a, b] = edges[e];
                return Err(SoftrodError::invalid(
                    format!("{field}.faces"),
                    format!("edge ({a}, {b})"),
                    "folds two triangles flat onto each other (their normals cancel), so the mesh has no outward side there; remove the fold",
                ));
            }
            edge_normals.push(s.map(|x| x / l));
        }
        let mut vertex_normals = Vec::with_capacity(vertices.len());
        let mut used = vec![false; vertices.len()];
        for t in faces {
            for &i in t {
                used[i] = true;
            }
        }
        for (i, s) in vertex_sum.iter().enumerate() {
            let l = norm(s);
            if !used[i] {
                vertex_normals.push([0.0; 3]);
                continue;
            }
            if l.is_nan() || l <= 1e-9 {
                return Err(SoftrodError::invalid(
                    format!("{field}.vertices[{i}]"),
                    format!("{:?}", vertices[i]),
                    "its triangles' angle-weighted normals cancel (a pinched or folded vertex), so the mesh has no outward side there; repair the mesh",
                ));
            }
            vertex_normals.push(s.map(|x| x / l));
        }
        let mut edge_faces = vec![[usize::MAX; 2]; edges.len()];
        let mut vertex_start = vec![0usize; vertices.len() + 1];
        for (f, t) in faces.iter().enumerate() {
            for k in 0..3 {
                let slot = &mut edge_faces[face_edges[f][k]];
                if slot[0] == usize::MAX {
                    slot[0] = f;
                } else {
                    slot[1] = f;
                }
                vertex_start[t[k] + 1] += 1;
            }
        }
        for i in 0..vertices.len() {
            vertex_start[i + 1] += vertex_start[i];
        }
        let mut fill = vertex_start.clone();
        let mut vertex_faces = vec![0usize; 3 * faces.len()];
        for (f, t) in faces.iter().enumerate() {
            for &v in t {
                vertex_faces[fill[v]] = f;
                fill[v] += 1;
            }
        }
        let border_edge: Vec<bool> = uses.iter().map(|&u| u == 1).collect();
        let border_edge_any = border_edge.iter().any(|&b| b);
        let mut border_vertex = vec![false; vertices.len()];
        for (e, &b) in edges.iter().zip(&border_edge) {
            if b {
                border_vertex[e[0]] = true;
                border_vertex[e[1]] = true;
            }
        }
        let mut mesh = TriMesh {
            vertices: vertices.to_vec(),
            faces: faces.to_vec(),
            face_normals,
            edges,
            face_edges,
            edge_normals,
            vertex_normals,
            border_edge,
            border_vertex,
            closed: !border_edge_any,
            edge_faces,
            vertex_start,
            vertex_faces,
            creased: Vec::new(),
            nodes: Vec::new(),
            order: (0..faces.len() as u32).collect(),
        };
        mesh.creased = (0..faces.len())
            .map(|a| {
                faces[a].iter().any(|&v| {
                    mesh.vertex_faces[mesh.vertex_start[v]..mesh.vertex_start[v + 1]]
                        .iter()
                        .any(|&f| f != a && mesh.concave(a, f))
                })
            })
            .collect();
        mesh.build();
        Ok(mesh)
    }

    fn bounds(&self, tris: &[u32]) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &t in tris {
            for &v in &self.faces[t as usize] {
                let p = self.vertices[v];
                for i in 0..3 {
                    lo[i] = lo[i].min(p[i]);
                    hi[i] = hi[i].max(p[i]);
                }
            }
        }
        (lo, hi)
    }

    /// The hierarchy: split at the median centroid along the box's longest side, down to
    /// `LEAF` triangles (balanced: depth about log2(n / LEAF)).
    fn build(&mut self) {
        let centroid: Vec<[f64; 3]> = self
            .faces
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i]);
                std::array::from_fn(|i| (a[i] + b[i] + c[i]) / 3.0)
            })
            .collect();
        let mut order = std::mem::take(&mut self.order);
        let mut nodes = Vec::with_capacity(2 * order.len() / LEAF + 2);
        let n = order.len();
        self.split(&centroid, &mut order, 0, n, &mut nodes);
        self.nodes = nodes;
        self.order = order;
    }

    /// Append the subtree of `order[a..b]` to `nodes` (its root first).
    fn split(
        &self,
        centroid: &[[f64; 3]],
        order: &mut [u32],
        a: usize,
        b: usize,
        nodes: &mut Vec<Node>,
    ) {
        let (lo, hi) = self.bounds(&order[a..b]);
        let node = nodes.len();
        nodes.push(Node {
            lo,
            hi,
            index: a as u32,
            count: (b - a) as u32,
        });
        if b - a <= LEAF {
            return;
        }
        let ext = sub(&hi, &lo);
        let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
            0
        } else if ext[1] >= ext[2] {
            1
        } else {
            2
        };
        let m = (a + b) / 2;
        order[a..b].select_nth_unstable_by(m - a, |x, y| {
            centroid[*x as usize][axis].total_cmp(&centroid[*y as usize][axis])
        });
        self.split(centroid, order, a, m, nodes);
        nodes[node].index = nodes.len() as u32;
        nodes[node].count = 0;
        self.split(centroid, order, m, b, nodes);
    }

    /// The nearest point of the mesh to p (finite): a depth-first descent of the hierarchy,
    /// nearer box first, skipping boxes farther than the best point so far.
    pub fn nearest(&self, p: &[f64; 3]) -> Nearest {
        let mut best = Nearest {
            point: [f64::NAN; 3],
            feature: Feature::Face(0),
            dist2: f64::INFINITY,
        };
        let box2 = |n: &Node| {
            let mut d2 = 0.0;
            for i in 0..3 {
                let d = (n.lo[i] - p[i]).max(p[i] - n.hi[i]).max(0.0);
                d2 += d * d;
            }
            d2
        };
        let mut stack: Vec<(usize, f64)> = Vec::with_capacity(64);
        stack.push((0, box2(&self.nodes[0])));
        while let Some((k, d2)) = stack.pop() {
            if d2 >= best.dist2 {
                continue;
            }
            let node = &self.nodes[k];
            if node.count > 0 {
                let a = node.index as usize;
                for &t in &self.order[a..a + node.count as usize] {
                    let c = self.closest_on_face(t as usize, p);
                    if c.dist2 < best.dist2 {
                        best = c;
                    }
                }
                continue;
            }
            let (l, r) = (k + 1, node.index as usize);
            let (dl, dr) = (box2(&self.nodes[l]), box2(&self.nodes[r]));
            // The nearer child is popped first.
            if dl <= dr {
                stack.push((r, dr));
                stack.push((l, dl));
            } else {
                stack.push((l, dl));
                stack.push((r, dr));
            }
        }
        best
    }

    /// The nearest point of p over every face, one by one (the reference for the tests).
    pub fn nearest_brute(&self, p: &[f64; 3]) -> Nearest {
        (0..self.faces.len())
            .map(|f| self.closest_on_face(f, p))
            .fold(None, |b: Option<Nearest>, c| match b {
                Some(b) if b.dist2 <= c.dist2 => Some(b),
                _ => Some(c),
            })
            .expect("a compiled mesh has at least one face")
    }

    /// The point of face f nearest to p and its feature (Ericson, "Real-Time Collision
    /// Detection", Morgan Kaufmann, 2005, section 5.1.5: the Voronoi regions of the
    /// triangle's corners, edges and interior, tested in that order).
    fn closest_on_face(&self, f: usize, p: &[f64; 3]) -> Nearest {
        let t = self.faces[f];
        let [a, b, c] = t.map(|i| self.vertices[i]);
        let out = |q: [f64; 3], feature: Feature| {
            let d = sub(p, &q);
            Nearest {
                point: q,
                feature,
                dist2: dot(&d, &d),
            }
        };
        let at = |u: &[f64; 3], s: f64, w: &[f64; 3]| -> [f64; 3] {
            std::array::from_fn(|i| u[i] + s * w[i])
        };
        let (ab, ac, ap) = (sub(&b, &a), sub(&c, &a), sub(p, &a));
        let (d1, d2) = (dot(&ab, &ap), dot(&ac, &ap));
        if d1 <= 0.0 && d2 <= 0.0 {
            return out(a, Feature::Vertex(t[0]));
        }
        let bp = sub(p, &b);
        let (d3, d4) = (dot(&ab, &bp), dot(&ac, &bp));
        if d3 >= 0.0 && d4 <= d3 {
            return out(b, Feature::Vertex(t[1]));
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let v = d1 / (d1 - d3);
            return out(at(&a, v, &ab), Feature::Edge(self.face_edges[f][0]));
        }
        let cp = sub(p, &c);
        let (d5, d6) = (dot(&ab, &cp), dot(&ac, &cp));
        if d6 >= 0.0 && d5 <= d6 {
            return out(c, Feature::Vertex(t[2]));
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let w = d2 / (d2 - d6);
            return out(at(&a, w, &ac), Feature::Edge(self.face_edges[f][2]));
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return out(
                at(&b, w, &sub(&c, &b)),
                Feature::Edge(self.face_edges[f][1]),
            );
        }
        let denom = 1.0 / (va + vb + vc);
        let (v, w) = (vb * denom, vc * denom);
        let q = std::array::from_fn(|i| a[i] + ab[i] * v + ac[i] * w);
        out(q, Feature::Face(f))
    }

    /// The feature whose own distance is the mesh's on a neighbourhood's side of p: the
    /// nearest point's feature, or a face or an edge around it when p - q is along that
    /// face's normal, or across that edge. An edge between two coplanar faces, or a vertex
    /// inside a flat patch, has a region of no volume (p sits on its border with a face's):
    /// the face's plane is then the distance on both sides, with the plane's derivatives
    /// (the edge's line or the vertex's point would give the right value and gradient but a
    /// curvature 1 / d the mesh does not have, which Newton's matrix and the stability
    /// assessment would see). At a genuine edge or corner the choice changes nothing but
    /// the side whose one-sided curvature is taken.
    pub fn exact_feature(&self, p: &[f64; 3], near: &Nearest) -> Feature {
        let w = sub(p, &near.point);
        let l2 = dot(&w, &w);
        // Parallel or perpendicular to 1e-10 (round-off in q is ~1e-16 relative).
        let tiny = 1e-20 * l2;
        if l2 == 0.0 {
            return near.feature;
        }
        let along_face = |f: usize| {
            let c = cross(&w, &self.face_normals[f]);
            dot(&c, &c) <= tiny
        };
        let across_edge = |e: usize| {
            let [i, j] = self.edges[e];
            let d = sub(&self.vertices[j], &self.vertices[i]);
            let a = dot(&w, &d);
            a * a <= tiny * dot(&d, &d)
        };
        match near.feature {
            Feature::Face(_) => near.feature,
            Feature::Edge(e) => self.edge_faces[e]
                .iter()
                .find(|&&f| f != usize::MAX && along_face(f))
                .map_or(near.feature, |&f| Feature::Face(f)),
            Feature::Vertex(v) => {
                let around = &self.vertex_faces[self.vertex_start[v]..self.vertex_start[v + 1]];
                if let Some(&f) = around.iter().find(|&&f| along_face(f)) {
                    return Feature::Face(f);
                }
                for &f in around {
                    let t = self.faces[f];
                    for k in 0..3 {
                        let e = self.face_edges[f][k];
                        if (t[k] == v || t[(k + 1) % 3] == v) && across_edge(e) {
                            return Feature::Edge(e);
                        }
                    }
                }
                near.feature
            }
        }
    }

    /// Whether a feature is on an open mesh's border (an edge of one face, or its end):
    /// a point nearest to it is outside (module docs).
    pub fn on_border(&self, feature: Feature) -> bool {
        match feature {
            Feature::Face(_) => false,
            Feature::Edge(e) => self.border_edge[e],
            Feature::Vertex(v) => self.border_vertex[v],
        }
    }

    /// Whether the mesh is closed (every edge shared by two faces).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The pseudo-normal of a feature (unit).
    pub fn pseudo_normal(&self, feature: Feature) -> [f64; 3] {
        match feature {
            Feature::Face(f) => self.face_normals[f],
            Feature::Edge(e) => self.edge_normals[e],
            Feature::Vertex(v) => self.vertex_normals[v],
        }
    }

    /// Signed distance of r from the mesh (positive outside) and the outward normal at its
    /// nearest point (module docs), generic in the scalar; within `blend` (m) of a concave
    /// crease's bisector, the smooth minimum of the faces there ([`TriMesh::blend_creases`];
    /// 0: the exact distance everywhere).
    #[inline]
    pub fn distance<D: RodScalar>(&self, r: &[D; 3], blend: f64) -> (D, [D; 3]) {
        let p = r.map(|x| x.value());
        if !p.iter().all(|x| x.is_finite()) {
            let nan = D::from(f64::NAN);
            return (nan, [nan; 3]);
        }
        let mut near = self.nearest(&p);
        near.feature = self.exact_feature(&p, &near);
        let pn = self.pseudo_normal(near.feature);
        let side = if !self.on_border(near.feature) && dot(&sub(&p, &near.point), &pn) < 0.0 {
            -1.0
        } else {
            1.0
        };
        let (d, nu) = self.feature_distance(r, near.feature, side);
        match near.feature {
            Feature::Face(a) if blend > 0.0 && d.value() > 0.0 && self.creased[a] => {
                self.blend_creases(r, &p, a, (d, nu), blend)
            }
            _ => (d, nu),
        }
    }

    /// The distance of r from one feature (face: its plane's; edge: its line's; vertex: its
    /// point's) with the sign `side`, and its gradient.
    #[inline]
    fn feature_distance<D: RodScalar>(
        &self,
        r: &[D; 3],
        feature: Feature,
        side: f64,
    ) -> (D, [D; 3]) {
        let pn = self.pseudo_normal(feature);
        match feature {
            Feature::Face(f) => {
                let n = self.face_normals[f];
                let a = self.vertices[self.faces[f][0]];
                let mut d = D::from(0.0);
                for k in 0..3 {
                    d += (r[k] - a[k]) * n[k];
                }
                (d, n.map(D::from))
            }
            Feature::Edge(e) => {
                let [i, j] = self.edges[e];
                let (a, b) = (self.vertices[i], self.vertices[j]);
                let ab = sub(&b, &a);
                let l = norm(&ab);
                let axis = ab.map(|x| x / l);
                let w: [D; 3] = std::array::from_fn(|k| r[k] - a[k]);
                let mut along = D::from(0.0);
                for k in 0..3 {
                    along += w[k] * axis[k];
                }
                signed(std::array::from_fn(|k| w[k] - along * axis[k]), side, pn)
            }
            Feature::Vertex(v) => {
                let a = self.vertices[v];
                signed(std::array::from_fn(|k| r[k] - a[k]), side, pn)
            }
        }
    }

    /// Whether faces a and b bend towards each other on the outward side (a crease or a
    /// hollow between them): each one's centroid lies above the other's plane.
    fn concave(&self, a: usize, b: usize) -> bool {
        let c = |f: usize| -> [f64; 3] {
            let [x, y, z] = self.faces[f].map(|i| self.vertices[i]);
            std::array::from_fn(|k| (x[k] + y[k] + z[k]) / 3.0)
        };
        let (ca, cb) = (c(a), c(b));
        let ab = sub(&cb, &ca);
        let tol = 1e-9 * norm(&ab);
        dot(&self.face_normals[a], &ab) > tol && -dot(&self.face_normals[b], &ab) > tol
    }

    /// The distance outside a concave crease, made C1 across its bisector. There the
    /// nearest point jumps from one face to the other and the normal with it (the bisector
    /// is the medial axis), which no single contact point per cross-section can balance (a
    /// rod along a V-groove). Within `beta` of the nearest face a's distance d, each face
    /// around a's corners that is concave with it (`concave`) and has p on its outward side
    /// enters a polynomial smooth minimum, smin(x, y) = min - h^2 beta / 4 with
    /// h = max(beta - |x - y|, 0) / beta, taken in order of the faces' indices (so the
    /// nearest face's neighbours agree about it where the nearest face changes). It is the
    /// exact distance wherever no other face is within beta, at most beta / 4 smaller per
    /// face within it, and its gradient, the force's direction, turns continuously from one
    /// face's normal to the other's. At most 64 other faces enter (those found first, around
    /// a's corners in order).
    fn blend_creases<D: RodScalar>(
        &self,
        r: &[D; 3],
        p: &[f64; 3],
        a: usize,
        exact: (D, [D; 3]),
        beta: f64,
    ) -> (D, [D; 3]) {
        // Other faces, plus a itself.
        const MOST: usize = 64;
        let mut ids = [usize::MAX; MOST + 1];
        let mut feats = [Feature::Face(a); MOST + 1];
        let mut n = 0;
        let reach = exact.0.value() + beta;
        for &v in &self.faces[a] {
            for &f in &self.vertex_faces[self.vertex_start[v]..self.vertex_start[v + 1]] {
                if f == a || n == MOST || ids[..n].contains(&f) || !self.concave(a, f) {
                    continue;
                }
                let near = self.closest_on_face(f, p);
                if near.dist2 >= reach * reach {
                    continue;
                }
                let feature = self.exact_feature(p, &near);
                if dot(&sub(p, &near.point), &self.pseudo_normal(feature)) <= 0.0 {
                    continue;
                }
                ids[n] = f;
                feats[n] = feature;
                n += 1;
            }
        }
        if n == 0 {
            return exact;
        }
        ids[n] = a;
        n += 1;
        // In order of face index: insertion sort of at most MOST entries.
        let mut order: [usize; MOST + 1] = std::array::from_fn(|k| k);
        for i in 1..n {
            let mut j = i;
            while j > 0 && ids[order[j - 1]] > ids[order[j]] {
                order.swap(j - 1, j);
                j -= 1;
            }
        }
        let value = |k: usize| {
            if ids[k] == a {
                exact
            } else {
                self.feature_distance(r, feats[k], 1.0)
            }
        };
        let mut acc = value(order[0]);
        for &k in &order[1..n] {
            acc = smin(acc, value(k), beta);
        }
        acc
    }

    /// Whether p is certainly farther than `c` outside a closed mesh: outside its box by at
    /// least c (a point outside the box of a closed mesh is outside the mesh, at least its
    /// distance from the box away). Never for an open mesh, whose inside (under it) reaches
    /// beyond its box.
    #[inline]
    pub fn surely_outside_by(&self, p: &[f64; 3], c: f64) -> bool {
        if !self.closed {
            return false;
        }
        let n = &self.nodes[0];
        let mut d2 = 0.0;
        for i in 0..3 {
            let d = (n.lo[i] - p[i]).max(p[i] - n.hi[i]).max(0.0);
            d2 += d * d;
        }
        // Outside the box (d2 > 0: then outside the mesh, d > 0) and by at least c.
        d2 > 0.0 && d2 >= c * c
    }

    /// The axis-aligned box of the whole mesh (lower and upper corners), m.
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        (self.nodes[0].lo, self.nodes[0].hi)
    }
}

/// The polynomial smooth minimum of two distances with their gradients (Quilez): the
/// smaller one where they differ by beta or more, else min - h^2 beta / 4 with
/// h = (beta - |x - y|) / beta, whose gradient (1 - h/2) grad min + (h/2) grad max is
/// continuous.
#[inline]
fn smin<D: RodScalar>(x: (D, [D; 3]), y: (D, [D; 3]), beta: f64) -> (D, [D; 3]) {
    let (lo, hi) = if x.0.value() <= y.0.value() {
        (x, y)
    } else {
        (y, x)
    };
    let gap = hi.0 - lo.0;
    if gap.value() >= beta {
        return lo;
    }
    let h = (gap * -1.0 + beta) / beta;
    let w = h * 0.5;
    let d = lo.0 - h * h * (0.25 * beta);
    let one = D::from(1.0);
    (
        d,
        std::array::from_fn(|k| lo.1[k] * (one - w) + hi.1[k] * w),
    )
}

/// Signed distance `side` |w| and outward normal `side` w / |w| from w, the offset of the
/// point from its nearest point on an edge or vertex; on the surface itself (w = 0) the
/// distance is 0 and the normal the feature's pseudo-normal `pn`.
#[inline]
fn signed<D: RodScalar>(w: [D; 3], side: f64, pn: [f64; 3]) -> (D, [D; 3]) {
    let n2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    if n2.value().is_nan() || n2.value() <= 0.0 {
        return (D::from(0.0), pn.map(D::from));
    }
    let n = n2.sqrt();
    let inv = n.recip() * side;
    (n * side, w.map(|x| x * inv))
}

/// A sphere of `radius` about `center` as a geodesic icosphere: the icosahedron with each
/// triangle split into four `level` times, the new vertices pushed onto the sphere
/// (20 * 4^level triangles, outward winding). For tests and examples.
pub fn icosphere(center: [f64; 3], radius: f64, level: u32) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let to_sphere = |p: [f64; 3]| {
        let l = norm(&p);
        p.map(|x| x / l)
    };
    v = v.into_iter().map(to_sphere).collect();
    for _ in 0..level {
        let mut mid: HashMap<[usize; 2], usize> = HashMap::new();
        let mut next = Vec::with_capacity(4 * f.len());
        for t in &f {
            let m: [usize; 3] = std::array::from_fn(|k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *mid.entry([a.min(b), a.max(b)]).or_insert_with(|| {
                    let p = std::array::from_fn(|i| 0.5 * (v[a][i] + v[b][i]));
                    v.push(to_sphere(p));
                    v.len() - 1
                })
            });
            next.push([t[0], m[0], m[2]]);
            next.push([t[1], m[1], m[0]]);
            next.push([t[2], m[2], m[1]]);
            next.push([m[0], m[1], m[2]]);
        }
        f = next;
    }
    let v = v
        .into_iter()
        .map(|p| std::array::from_fn(|i| center[i] + radius * p[i]))
        .collect();
    (v, f)
}

/// The box [lo, hi] as 12 triangles (two per side, outward winding). For tests and
/// examples.
pub fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let v = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        })
        .collect();
    // Each side as a quad, counter-clockwise seen from outside.
    let quads = [
        [0, 2, 3, 1], // z = lo
        [4, 5, 7, 6], // z = hi
        [0, 1, 5, 4], // y = lo
        [2, 6, 7, 3], // y = hi
        [0, 4, 6, 2], // x = lo
        [1, 3, 7, 5], // x = hi
    ];
    let f = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (v, f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jet::Jet;

    /// The crease blending width the tests pass: it must change nothing on convex and flat
    /// meshes (no concave pair of faces), which the exact checks below then confirm.
    const B: f64 = 0.01;

    /// A xorshift generator: reproducible points without a dependency.
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self, a: f64, b: f64) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            a + (b - a) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
        }
        fn point(&mut self, a: f64, b: f64) -> [f64; 3] {
            [self.uniform(a, b), self.uniform(a, b), self.uniform(a, b)]
        }
    }

    fn mesh((v, f): (Vec<[f64; 3]>, Vec<[usize; 3]>)) -> TriMesh {
        TriMesh::new("obstacles[0]", &v, &f).unwrap()
    }

    /// A bumpy open terrain patch of n x n squares over [-1, 1]^2 (normals up).
    fn terrain(n: usize) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
        let mut v = vec![];
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (
                    -1.0 + 2.0 * i as f64 / n as f64,
                    -1.0 + 2.0 * j as f64 / n as f64,
                );
                v.push([x, y, 0.2 * (3.0 * x).sin() * (2.0 * y).cos()]);
            }
        }
        let mut f = vec![];
        for j in 0..n {
            for i in 0..n {
                let a = j * (n + 1) + i;
                f.push([a, a + 1, a + n + 2]);
                f.push([a, a + n + 2, a + n + 1]);
            }
        }
        (v, f)
    }

    /// Property: the hierarchy's nearest point is the brute-force one (the same per-face
    /// arithmetic, so the same squared distance to the last bit) for random points near
    /// and far from a closed and an open mesh.
    #[test]
    fn hierarchy_matches_brute_force() {
        let mut rng = Rng(0x9e3779b97f4a7c15);
        for m in [mesh(icosphere([0.1, -0.2, 0.3], 0.7, 3)), mesh(terrain(23))] {
            for _ in 0..3000 {
                let p = rng.point(-2.0, 2.0);
                let (a, b) = (m.nearest(&p), m.nearest_brute(&p));
                assert_eq!(a.dist2, b.dist2, "at {p:?}");
            }
        }
    }

    /// The exact signed distance of the box [-h, h]^3 (Quilez's closed form).
    fn box_sdf(p: &[f64; 3], h: &[f64; 3]) -> f64 {
        let q: [f64; 3] = std::array::from_fn(|i| p[i].abs() - h[i]);
        let out = norm(&q.map(|x| x.max(0.0)));
        out + q[0].max(q[1]).max(q[2]).min(0.0)
    }

    /// A 12-triangle box's signed distance equals the exact box distance everywhere:
    /// outside (face, edge and corner regions), inside, and across the sides' diagonals.
    /// To round-off: |d| ~ 1, each step a few ulps (1e-14 allows 50 of them).
    #[test]
    fn cube_distance_is_the_box_distance() {
        let h = [0.5, 0.3, 0.2];
        let m = mesh(cuboid(h.map(|x| -x), h));
        let mut rng = Rng(12345);
        let mut regions = [0usize; 3];
        for _ in 0..20000 {
            let p = rng.point(-1.2, 1.2);
            let (d, nu) = m.distance::<f64>(&p, B);
            assert!(
                (d - box_sdf(&p, &h)).abs() < 1e-14,
                "{p:?}: {d} vs {}",
                box_sdf(&p, &h)
            );
            // The nearest point r - d nu is on the box's surface.
            let q: [f64; 3] = std::array::from_fn(|i| p[i] - d * nu[i]);
            assert!(box_sdf(&q, &h).abs() < 1e-14);
            // The box test that skips far points never skips a nearer one.
            // (c = 0 too: a centreline without a surface radius.)
            let c = if rng.uniform(0.0, 1.0) < 0.2 {
                0.0
            } else {
                rng.uniform(0.0, 0.5)
            };
            if m.surely_outside_by(&p, c) {
                assert!(d >= c && d > 0.0, "{p:?} skipped at {c} but d = {d}");
            }
            match m.nearest(&p).feature {
                Feature::Face(_) => regions[0] += 1,
                Feature::Edge(_) => regions[1] += 1,
                Feature::Vertex(_) => regions[2] += 1,
            }
        }
        // Every kind of feature was the nearest one somewhere.
        assert!(regions.iter().all(|&n| n > 100), "{regions:?}");
    }

    /// An icosphere inscribed in a sphere contains the ball of its smallest face distance
    /// r_in, so (distance being monotone in the set) 0 <= d_mesh - d_sphere <= R - r_in
    /// everywhere; R - r_in shrinks about 4 times per subdivision (the sagitta of a chord
    /// of half the length), and d_mesh converges to d_sphere.
    #[test]
    fn icosphere_converges_to_the_sphere() {
        let (c, radius) = ([0.01, 0.02, -0.03], 0.05);
        let mut rng = Rng(777);
        let mut last = f64::INFINITY;
        for level in 1..=5 {
            let m = mesh(icosphere(c, radius, level));
            let r_in = m
                .faces
                .iter()
                .enumerate()
                .map(|(f, t)| dot(&sub(&c, &m.vertices[t[0]]), &m.face_normals[f]).abs())
                .fold(f64::INFINITY, f64::min);
            let bound = radius - r_in;
            let mut worst: f64 = 0.0;
            for _ in 0..2000 {
                let p = rng.point(-0.12, 0.12);
                let p = std::array::from_fn(|i| c[i] + p[i]);
                let exact = norm(&sub(&p, &c)) - radius;
                let (d, _) = m.distance::<f64>(&p, B);
                let gap = d - exact;
                assert!(
                    gap >= -1e-15 && gap <= bound + 1e-15,
                    "level {level}: {gap} vs {bound}"
                );
                worst = worst.max(gap);
            }
            assert!(bound < last / 3.5, "level {level}: {bound} after {last}");
            last = bound;
        }
        // Level 5 (20480 triangles): edges e of at most about 1.1 R / 32 (the
        // icosahedron's edge 1.05 R halved five times, stretched a little by the
        // projection), circumradius e / sqrt 3, so R - r_in ~ e^2 / (6 R) ~ 2e-4 R.
        assert!(last < 3e-4 * radius, "{last}");
    }

    /// Dual-number derivatives of the distance equal central differences, and the normal
    /// is the distance's gradient, in face, edge and vertex regions outside and inside.
    /// d is smooth within a region: with h = 1e-6 the difference errs by h^2 |d'''| / 6
    /// (d''' ~ 1 / distance^2 ~ 100 here: 2e-11) plus round-off 1e-16 / h = 1e-10.
    #[test]
    fn derivatives_match_finite_differences() {
        let h = [0.5, 0.3, 0.2];
        let m = mesh(cuboid(h.map(|x| -x), h));
        let probes = [
            ([0.1, 0.05, 0.35], "face outside"),
            ([0.1, 0.05, 0.1], "face inside"),
            ([0.7, 0.1, 0.4], "edge"),
            ([0.7, -0.5, 0.4], "vertex"),
        ];
        for (p, what) in probes {
            let kind = m.nearest(&p).feature;
            let want = match what {
                "edge" => matches!(kind, Feature::Edge(_)),
                "vertex" => matches!(kind, Feature::Vertex(_)),
                _ => matches!(kind, Feature::Face(_)),
            };
            assert!(want, "{what}: {kind:?}");
            let r: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable(p[i], i));
            let (d, nu) = m.distance(&r, B);
            for j in 0..3 {
                let step = 1e-6;
                let (mut a, mut b) = (p, p);
                a[j] += step;
                b[j] -= step;
                let fd = (m.distance::<f64>(&a, B).0 - m.distance::<f64>(&b, B).0) / (2.0 * step);
                assert!(
                    (fd - d.eps[j]).abs() < 1e-8,
                    "{what} d/d{j}: {fd} {}",
                    d.eps[j]
                );
                assert!((nu[j].re - d.eps[j]).abs() < 1e-12, "{what}: normal {j}");
                for i in 0..3 {
                    let fd = (m.distance::<f64>(&a, B).1[i] - m.distance::<f64>(&b, B).1[i])
                        / (2.0 * step);
                    assert!((fd - nu[i].eps[j]).abs() < 1e-7, "{what} dnu{i}/d{j}");
                }
            }
        }
    }

    /// An open patch: below its normals is inside, beyond its border the sign follows
    /// the border's pseudo-normal, and the distance is C1 across a face/edge border.
    #[test]
    fn open_mesh_sides() {
        let v = vec![
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
        ];
        let f = vec![[0, 1, 2], [0, 2, 3]];
        let m = mesh((v, f));
        assert_eq!(m.distance::<f64>(&[0.2, 0.3, 0.1], B).0, 0.1);
        assert_eq!(m.distance::<f64>(&[0.2, 0.3, -0.1], B).0, -0.1);
        let (d, nu) = m.distance::<f64>(&[1.3, 0.0, 0.4], B);
        assert!((d - 0.5).abs() < 1e-15 && (nu[0] - 0.6).abs() < 1e-15);
        // Beyond the border a point is outside from any side (the edge of a sheet).
        let (d, nu) = m.distance::<f64>(&[1.3, 0.0, -0.4], B);
        assert!((d - 0.5).abs() < 1e-15 && (nu[2] + 0.8).abs() < 1e-15);
        assert!(!m.is_closed());
        // Under an open patch, beyond its box, is still inside: never skipped.
        assert!(!m.surely_outside_by(&[0.0, 0.0, -5.0], 1.0));
        assert!(m.distance::<f64>(&[0.0, 0.0, -5.0], B).0 == -5.0);
        // Value and slope agree on both sides of the border x = 1 (z = 0.2 above).
        let g = |x: f64| m.distance::<f64>(&[x, 0.1, 0.2], B).0;
        let e = 1e-9;
        assert!((g(1.0 - e) - g(1.0 + e)).abs() < 1e-12);
        let slope = |x: f64| (g(x + 1e-7) - g(x - 1e-7)) / 2e-7;
        assert!((slope(1.0 - 1e-6) - slope(1.0 + 1e-6)).abs() < 1e-4);
    }

    /// Above a flat grid's edges and vertices (regions of no volume) the distance is the
    /// plane's, with its derivatives: the normal does not turn (the line's or the point's
    /// distance would curve by 1 / d there). Across a genuine ridge it does.
    #[test]
    fn flat_edges_and_vertices_are_the_plane() {
        let n = 4;
        let mut v = vec![];
        for j in 0..=n {
            for i in 0..=n {
                v.push([i as f64 - 2.0, j as f64 - 2.0, 0.0]);
            }
        }
        let mut f = vec![];
        for j in 0..n {
            for i in 0..n {
                let a = j * (n + 1) + i;
                f.push([a, a + 1, a + n + 2]);
                f.push([a, a + n + 2, a + n + 1]);
            }
        }
        let m = mesh((v, f));
        // Above a grid line (edge), a diagonal (edge) and a grid point (vertex), outside
        // and inside.
        for p in [
            [0.3, 0.0, 0.2],
            [0.5, 0.5, 0.2],
            [1.0, 1.0, 0.2],
            [0.0, 1.0, -0.1],
        ] {
            let r: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable(p[i], i));
            let (d, nu) = m.distance(&r, B);
            assert_eq!(d.re, p[2]);
            assert_eq!(d.eps, [0.0, 0.0, 1.0], "{p:?}");
            for k in 0..3 {
                assert_eq!(nu[k].eps, [0.0; 3], "{p:?}");
            }
        }
        // A roof ridge along y (faces tilted +-45 degrees): above it the normal turns.
        let roof = vec![
            [-1.0, -1.0, 0.0],
            [0.0, -1.0, 1.0],
            [1.0, -1.0, 0.0],
            [-1.0, 1.0, 0.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 0.0],
        ];
        let m = mesh((roof, vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]]));
        let r: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable([0.0, 0.0, 1.5][i], i));
        let (d, nu) = m.distance(&r, B);
        assert!((d.re - 0.5).abs() < 1e-15 && (nu[0].eps[0] - 2.0).abs() < 1e-12);
    }

    /// A V-groove (two slopes of 0.2 over 1 meeting in a crease along y): the exact distance
    /// above it has a kink on the bisector x = 0, the normal jumping from one slope's to
    /// the other's; blended over beta it is the exact distance wherever the slopes'
    /// distances differ by beta or more, within beta / 4 below it elsewhere, C1 across the
    /// bisector (the normal there the mean of the two), with exact dual derivatives.
    #[test]
    fn concave_creases_are_blended() {
        let v = vec![
            [-1.0, -1.0, 0.2],
            [0.0, -1.0, 0.0],
            [1.0, -1.0, 0.2],
            [-1.0, 1.0, 0.2],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.2],
        ];
        let f = vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]];
        let m = mesh((v, f));
        let beta = 0.02;
        let at = |x: f64, b: f64| m.distance::<f64>(&[x, 0.1, 0.3], b);
        let mut inside = 0;
        for k in -200..=200 {
            let x = 1e-3 * k as f64;
            let (exact, blended) = (at(x, 0.0).0, at(x, beta).0);
            assert!(
                blended <= exact && blended >= exact - 0.25 * beta,
                "{x}: {blended} {exact}"
            );
            if blended < exact {
                inside += 1;
            }
        }
        // The band is narrow: |d_A - d_B| = 2 |x| sin(atan 0.2) < beta for |x| < 0.051.
        assert!(inside > 50 && inside < 110, "{inside}");
        // Far from the bisector, exact to the bit.
        assert_eq!(at(0.15, beta).0, at(0.15, 0.0).0);
        // C1 across the bisector: the exact slope jumps by -2 sin(atan 0.2) (from the left
        // slope's normal, tilted to +x, to the right one's, tilted to -x), the blended one
        // is continuous (0 at x = 0 by symmetry).
        let slope = |x: f64, b: f64| (at(x + 1e-7, b).0 - at(x - 1e-7, b).0) / 2e-7;
        let jump = 2.0 * 0.2f64.atan().sin();
        assert!((slope(1e-5, 0.0) - slope(-1e-5, 0.0) + jump).abs() < 1e-6);
        assert!((slope(1e-5, beta) - slope(-1e-5, beta)).abs() < 1e-2);
        assert!(at(0.0, beta).1[0].abs() < 1e-15);
        // The gradient is the normal, and the duals are exact, inside the band.
        for x in [-0.02, 0.004, 0.03] {
            let p = [x, 0.1, 0.3];
            let r: [Jet<3>; 3] = std::array::from_fn(|i| Jet::variable(p[i], i));
            let (d, nu) = m.distance(&r, beta);
            for j in 0..3 {
                let (mut a, mut b) = (p, p);
                a[j] += 1e-6;
                b[j] -= 1e-6;
                let fd = (m.distance::<f64>(&a, beta).0 - m.distance::<f64>(&b, beta).0) / 2e-6;
                assert!(
                    (fd - d.eps[j]).abs() < 1e-7,
                    "{x} d/d{j}: {fd} {}",
                    d.eps[j]
                );
                assert!((nu[j].re - d.eps[j]).abs() < 1e-12);
                for i in 0..3 {
                    let fd = (m.distance::<f64>(&a, beta).1[i] - m.distance::<f64>(&b, beta).1[i])
                        / 2e-6;
                    assert!(
                        (fd - nu[i].eps[j]).abs() < 1e-5 * (1.0 + fd.abs()),
                        "{x} dnu{i}/d{j}"
                    );
                }
            }
        }
    }

    /// A hollow cone of 100 faces around its apex (a bowl's bottom): above the apex every
    /// face is within the blending width, more than enter the blend (64): finite, no
    /// deeper than the exact distance and within (64 beta / 4) of it.
    #[test]
    fn a_hollow_apex_with_many_faces_blends_within_bounds() {
        let n = 100;
        let mut v = vec![[0.0, 0.0, 0.0]];
        for k in 0..n {
            let t = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            v.push([t.cos(), t.sin(), 0.3]);
        }
        let f: Vec<[usize; 3]> = (0..n).map(|k| [0, 1 + k, 1 + (k + 1) % n]).collect();
        let m = mesh((v, f));
        let beta = 0.01;
        for p in [[0.0, 0.0, 0.1], [1e-4, -2e-4, 0.05], [0.01, 0.0, 0.2]] {
            let (exact, blended) = (m.distance::<f64>(&p, 0.0), m.distance::<f64>(&p, beta));
            assert!(blended.0.is_finite() && blended.1.iter().all(|x| x.is_finite()));
            assert!(
                blended.0 <= exact.0 && blended.0 >= exact.0 - 16.0 * beta,
                "{p:?}"
            );
        }
    }

    /// The rules, each named with its field.
    #[test]
    fn bad_meshes_are_refused() {
        let (v, f) = cuboid([0.0; 3], [1.0; 3]);
        let err = |v: &[[f64; 3]], f: &[[usize; 3]]| {
            TriMesh::new("obstacles[2]", v, f).unwrap_err().to_string()
        };
        let mut w = v.clone();
        w[3][1] = f64::NAN;
        assert!(err(&w, &f).contains("obstacles[2].vertices[3][1]"));
        w[3][1] = 1e4;
        assert!(err(&w, &f).contains("within"));
        let mut g = f.clone();
        g[5][2] = 8;
        assert!(err(&v, &g).contains("obstacles[2].faces[5][2]"));
        let mut g = f.clone();
        g[4] = [0, 1, 1];
        assert!(
            err(&v, &g).contains("obstacles[2].faces[4]") && err(&v, &g).contains("degenerate")
        );
        let mut g = f.clone();
        g[7] = [g[7][0], g[7][2], g[7][1]];
        assert!(err(&v, &g).contains("winding"));
        let mut g = f.clone();
        g.push(f[0]);
        assert!(err(&v, &g).contains("faces[12]"));
        assert!(err(&v, &[]).contains("at least one"));
        // Collinear corners: zero area.
        let line = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!(err(&line, &[[0, 1, 2]]).contains("degenerate"));
    }
}
