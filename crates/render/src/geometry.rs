//! The renderer's geometry: the scene's meshes as they are (the default, the reference
//! look), or, opt-in, simplified for the image size. On a CPU rasterizer the DexJoCo
//! reference scenes cost mostly triangles (the hammer_nail scene draws about 187,000 into
//! 50,176 pixels at 224 px); simplifying each mesh until its surface moves by at most half
//! a pixel (meshoptimizer, edge collapses with an absolute error bound) removes most of
//! them. Only the copy of the model the renderer uploads is simplified: collision meshes,
//! physics and every other use of the model are untouched.

use std::collections::HashMap;

use mujoco_rs::prelude::MjModel;
use serde::{Deserialize, Serialize};

/// How much of the meshes' detail the renderer draws.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Geometry {
    /// The meshes as the scene has them.
    #[default]
    Full,
    /// Each mesh simplified until its surface moves by at most half a pixel of the image
    /// seen from 1 m with a 45° field of view ([`Geometry::max_error`]).
    Light,
}

impl Geometry {
    /// The default, full geometry (for `skip_serializing_if`).
    pub fn is_full(&self) -> bool {
        *self == Self::Full
    }

    /// `full` or `light`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::Light => "light",
        }
    }

    /// The largest distance, in metres, a light mesh's surface may move for images
    /// `height` pixels high: half a pixel at 1 m with a 45° vertical field of view (the
    /// reference cameras look from 1.4 m and 2.4 m, so the error there is smaller still).
    pub fn max_error(height: u32) -> f32 {
        const NEAR_M: f64 = 1.0;
        const FOVY_DEG: f64 = 45.0;
        let pixel = 2.0 * NEAR_M * (FOVY_DEG.to_radians() / 2.0).tan() / f64::from(height.max(1));
        (0.5 * pixel) as f32
    }
}

/// A model whose meshes were simplified for drawing.
pub(crate) struct Lightened {
    /// The copy with simplified meshes.
    pub model: MjModel,
    /// Its mesh triangles.
    pub triangles_after: usize,
}

/// Meshes with fewer triangles are left as they are (nothing to gain).
const MIN_TRIANGLES: usize = 64;

/// One face corner of a mesh as MuJoCo stores it: indices of its vertex, normal and
/// texture coordinate (0 without texture), the normal's direction and the texture
/// coordinate's value (0, 0 without texture).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Corner {
    vertex: i32,
    normal: i32,
    texcoord: i32,
    direction: [f32; 3],
    uv: [f32; 2],
}

/// Mesh triangles of `model`.
pub(crate) fn mesh_triangles(model: &MjModel) -> usize {
    model.ffi().nmeshface as usize
}

/// A copy of `model` whose meshes are simplified to `max_error` metres.
pub(crate) fn lighten(model: &MjModel, max_error: f32) -> Lightened {
    let mut copy = model.clone();
    let mut after = 0;
    // SAFETY: `copy` is a complete model owned here; each mesh's arrays are read and
    // written within the ranges its own address and count fields give (its faces are
    // rewritten in place, fewer than before, with vertex, normal and texture-coordinate
    // indices taken from its original faces).
    let m = unsafe { copy.ffi_mut() };
    for i in 0..m.nmesh as usize {
        // SAFETY: i < nmesh.
        let (fadr, fnum) = unsafe {
            (
                *m.mesh_faceadr.add(i) as usize,
                *m.mesh_facenum.add(i) as usize,
            )
        };
        if fnum < MIN_TRIANGLES {
            after += fnum;
            continue;
        }
        // SAFETY: mesh i's faces, vertices, normals and texture coordinates, as MuJoCo
        // laid them out.
        let (corners, positions) = unsafe { mesh_corners(m, i) };
        let faces = simplify(&corners, |v| positions[v as usize], max_error);
        if faces.is_empty() {
            // Simplified away entirely (a small, dense part): drawn as it is.
            after += fnum;
            continue;
        }
        after += faces.len();
        // SAFETY: i < nmesh.
        let textured = unsafe { *m.mesh_texcoordadr.add(i) } >= 0;
        for (j, face) in faces.iter().enumerate() {
            for (k, c) in face.iter().enumerate() {
                let at = 3 * (fadr + j) + k;
                // SAFETY: j < faces.len() <= fnum: inside the mesh's own face range; face
                // texture coordinates exist when the mesh has any.
                unsafe {
                    *m.mesh_face.add(at) = c.vertex;
                    *m.mesh_facenormal.add(at) = c.normal;
                    if textured {
                        *m.mesh_facetexcoord.add(at) = c.texcoord;
                    }
                }
            }
        }
        // SAFETY: i < nmesh.
        unsafe { *m.mesh_facenum.add(i) = faces.len() as i32 };
    }
    Lightened {
        model: copy,
        triangles_after: after,
    }
}

/// Mesh `i`'s face corners and vertex positions.
///
/// # Safety
/// `m` is a complete model and `i < m.nmesh`.
unsafe fn mesh_corners(m: &mujoco_rs::mujoco_c::mjModel, i: usize) -> (Vec<Corner>, Vec<[f32; 3]>) {
    // SAFETY: every index below stays inside mesh i's ranges of the arrays, per MuJoCo's
    // layout: faces [faceadr, faceadr + facenum), vertices [vertadr, vertadr + vertnum),
    // normal and texture-coordinate indices relative to normaladr and texcoordadr (face
    // texture coordinates exist only when texcoordadr >= 0).
    unsafe {
        let vadr = *m.mesh_vertadr.add(i) as usize;
        let vnum = *m.mesh_vertnum.add(i) as usize;
        let nadr = *m.mesh_normaladr.add(i) as usize;
        let (fadr, fnum) = (
            *m.mesh_faceadr.add(i) as usize,
            *m.mesh_facenum.add(i) as usize,
        );
        let tadr = *m.mesh_texcoordadr.add(i);
        let xyz = |p: *const f32, k: usize| [*p.add(3 * k), *p.add(3 * k + 1), *p.add(3 * k + 2)];
        let positions = (0..vnum).map(|v| xyz(m.mesh_vert, vadr + v)).collect();
        let corners = (0..3 * fnum)
            .map(|c| {
                let at = 3 * fadr + c;
                let (vertex, normal) = (*m.mesh_face.add(at), *m.mesh_facenormal.add(at));
                let (texcoord, uv) = if tadr >= 0 {
                    let t = *m.mesh_facetexcoord.add(at);
                    let uv = m.mesh_texcoord.add(2 * (tadr as usize + t as usize));
                    (t, [*uv, *uv.add(1)])
                } else {
                    (0, [0.0; 2])
                };
                Corner {
                    vertex,
                    normal,
                    texcoord,
                    direction: xyz(m.mesh_normal, nadr + normal as usize),
                    uv,
                }
            })
            .collect();
        (corners, positions)
    }
}

/// Simplifies one mesh given as face corners (three per face). Mesh files often repeat a
/// vertex for every face that uses it (the reference Panda links: 44,200 vertices at
/// 7,414 places), so the corners are first welded by position and texture coordinate,
/// for meshoptimizer to see the surface rather than loose triangles (and a texture seam
/// as a seam, which it keeps). Each corner of a new face then takes, of the original
/// corners at its place, the one whose normal is closest to the new face's: a sharp edge
/// keeps a normal on each side.
fn simplify(
    corners: &[Corner],
    position: impl Fn(i32) -> [f32; 3],
    max_error: f32,
) -> Vec<[Corner; 3]> {
    let mut welded: HashMap<[u32; 5], u32> = HashMap::new();
    let mut xyz: Vec<[f32; 3]> = Vec::new();
    let mut at_place: Vec<Vec<Corner>> = Vec::new();
    let indices: Vec<u32> = corners
        .iter()
        .map(|c| {
            let p = position(c.vertex);
            // `+ 0.0` makes -0.0 and 0.0 one place.
            let bits = |x: f32| (x + 0.0).to_bits();
            let key = [
                bits(p[0]),
                bits(p[1]),
                bits(p[2]),
                bits(c.uv[0]),
                bits(c.uv[1]),
            ];
            let w = *welded.entry(key).or_insert_with(|| {
                xyz.push(p);
                at_place.push(Vec::new());
                (xyz.len() - 1) as u32
            });
            let here = &mut at_place[w as usize];
            if !here.contains(c) {
                here.push(*c);
            }
            w
        })
        .collect();
    let bytes = meshopt::typed_to_bytes(&xyz);
    let adapter = meshopt::VertexDataAdapter::new(bytes, std::mem::size_of::<[f32; 3]>(), 0)
        .expect("three floats per vertex");
    let kept = meshopt::simplify(
        &indices,
        &adapter,
        0,
        max_error,
        meshopt::SimplifyOptions::ErrorAbsolute,
        None,
    );
    kept.chunks_exact(3)
        .map(|f| {
            let n = face_normal(xyz[f[0] as usize], xyz[f[1] as usize], xyz[f[2] as usize]);
            let pick = |w: u32| {
                *at_place[w as usize]
                    .iter()
                    .max_by(|a, b| dot(a.direction, n).total_cmp(&dot(b.direction, n)))
                    .expect("every place has a corner")
            };
            [pick(f[0]), pick(f[1]), pick(f[2])]
        })
        .collect()
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The unit normal of a triangle (counter-clockwise), or zero for a degenerate one.
fn face_normal(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> [f32; 3] {
    let (u, v) = (
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
        [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
    );
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let len = dot(n, n).sqrt();
    if len > 0.0 {
        n.map(|x| x / len)
    } else {
        [0.0; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A finely tessellated flat square (2 n^2 triangles, normal +z), stored as a mesh file
    /// often stores it: every face with vertices of its own.
    fn grid(n: i32) -> (Vec<Corner>, Vec<[f32; 3]>) {
        let at = |x: i32, y: i32| [x as f32 / n as f32, y as f32 / n as f32, 0.0];
        let mut corners = Vec::new();
        let mut vertices = Vec::new();
        for y in 0..n {
            for x in 0..n {
                for p in [
                    at(x, y),
                    at(x + 1, y),
                    at(x + 1, y + 1),
                    at(x, y),
                    at(x + 1, y + 1),
                    at(x, y + 1),
                ] {
                    vertices.push(p);
                    let v = vertices.len() as i32 - 1;
                    corners.push(Corner {
                        vertex: v,
                        normal: v,
                        texcoord: v,
                        direction: [0.0, 0.0, 1.0],
                        uv: [0.0; 2],
                    });
                }
            }
        }
        (corners, vertices)
    }

    #[test]
    fn loose_triangles_of_a_flat_mesh_are_welded_and_simplified_to_its_outline() {
        let (corners, vertices) = grid(16);
        let faces = simplify(&corners, |v| vertices[v as usize], 1e-3);
        assert!(!faces.is_empty());
        assert!(
            faces.len() <= 8,
            "{} of {} faces left",
            faces.len(),
            corners.len() / 3
        );
        // The square's corners stay, every new corner is an old one, faces still face +z.
        let places: Vec<[f32; 3]> = faces
            .iter()
            .flatten()
            .map(|c| vertices[c.vertex as usize])
            .collect();
        for corner in [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ] {
            assert!(places.contains(&corner), "corner {corner:?} dropped");
        }
        for f in &faces {
            assert!(f.iter().all(|c| corners.contains(c)));
            let n = face_normal(
                vertices[f[0].vertex as usize],
                vertices[f[1].vertex as usize],
                vertices[f[2].vertex as usize],
            );
            assert!(n[2] > 0.99, "{n:?}");
        }
    }

    #[test]
    fn the_error_bound_is_half_a_pixel_at_one_metre() {
        // 2 tan(22.5 deg) / 224 / 2 = 1.85 mm.
        assert!((Geometry::max_error(224) - 1.849e-3).abs() < 1e-5);
        assert!(Geometry::max_error(640) < Geometry::max_error(224));
    }
}
