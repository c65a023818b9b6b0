//! The crate's guarantee, checked against the reference: on every corner where
//! `bevy_mikktspace` 1.0 (a byte-exact port of the MikkTSpace C code) emits a valid tangent,
//! `Method::MikkTSpace` emits the same bits, on one thread and on many.
//!
//! Self-contained on purpose (meshes generated here, no fixtures), so the crate tests alone.
//! The project's `tests/oracle.rs` does the same on real files from `fixtures/` and the corpus.

use tspace_tangent::{MeshInput, Options, UvOrigin, generate};

struct Mesh {
    name: &'static str,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

/// The reference's tangents, one per corner (`None` where it assigns none).
fn reference(mesh: &Mesh) -> Vec<Option<[f32; 4]>> {
    struct Geometry<'a> {
        mesh: &'a Mesh,
        out: Vec<Option<[f32; 4]>>,
    }
    impl Geometry<'_> {
        fn vertex(&self, face: usize, vert: usize) -> usize {
            self.mesh.indices[face * 3 + vert] as usize
        }
    }
    impl bevy_mikktspace::Geometry for Geometry<'_> {
        fn num_faces(&self) -> usize {
            self.mesh.indices.len() / 3
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.mesh.positions[self.vertex(face, vert)]
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            self.mesh.normals[self.vertex(face, vert)]
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            self.mesh.uvs[self.vertex(face, vert)]
        }
        fn set_tangent(
            &mut self,
            tangent: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            self.out[face * 3 + vert] = tangent.map(|t| t.tangent_encoded());
        }
    }
    let mut geometry = Geometry {
        mesh,
        out: vec![None; mesh.indices.len()],
    };
    bevy_mikktspace::generate_tangents(&mut geometry).expect("the reference runs");
    geometry.out
}

/// Finite, unit and orthogonal to the normal: a tangent the crate passes through unchanged.
fn is_valid(t: [f32; 4], n: [f32; 3]) -> bool {
    let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let dot = (t[0] * n[0] + t[1] * n[1] + t[2] * n[2]) / length;
    let unit = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    t.iter().all(|x| x.is_finite()) && (unit - 1.0).abs() < 8e-6 && dot.abs() < 4e-5
}

/// A grid of `columns` × `rows` quads on a surface `f(u, v) -> (position, normal)`, with its UVs
/// scaled by `uv_scale` (negative components mirror) and every vertex shared by its quads.
fn grid(
    name: &'static str,
    columns: u32,
    rows: u32,
    uv_scale: [f32; 2],
    surface: impl Fn(f32, f32) -> ([f32; 3], [f32; 3]),
) -> Mesh {
    let mut mesh = Mesh {
        name,
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
    };
    for row in 0..=rows {
        for column in 0..=columns {
            let (u, v) = (column as f32 / columns as f32, row as f32 / rows as f32);
            let (position, normal) = surface(u, v);
            mesh.positions.push(position);
            mesh.normals.push(normal);
            mesh.uvs.push([u * uv_scale[0], v * uv_scale[1]]);
        }
    }
    let at = |column: u32, row: u32| row * (columns + 1) + column;
    for row in 0..rows {
        for column in 0..columns {
            let quad = [
                at(column, row),
                at(column + 1, row),
                at(column + 1, row + 1),
                at(column, row + 1),
            ];
            mesh.indices
                .extend([quad[0], quad[1], quad[2], quad[0], quad[2], quad[3]]);
        }
    }
    mesh
}

fn torus(u: f32, v: f32) -> ([f32; 3], [f32; 3]) {
    use std::f32::consts::TAU;
    let (a, b) = (u * TAU, v * TAU);
    let normal = [a.cos() * b.cos(), a.sin() * b.cos(), b.sin()];
    let ring = [a.cos() * 2.0, a.sin() * 2.0, 0.0];
    let position = [
        ring[0] + 0.5 * normal[0],
        ring[1] + 0.5 * normal[1],
        0.5 * normal[2],
    ];
    (position, normal)
}

/// Flat discs, each a fan of `n` triangles around its centre, whose UVs go `m` times around
/// the centre's: the triangles' frames turn `m - 1` times around it, so that at the centre
/// they spread over every direction, in one group. Where `n` is even, opposite rim points are
/// exact negatives; where `m` is even too, they also have equal UVs, so that opposite
/// triangles have exactly opposite frames, and the reference may split the centre into
/// sub-groups.
fn twisted_discs() -> Mesh {
    let mut mesh = Mesh {
        name: "twisted discs",
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
    };
    let mut offset = 0.0f32;
    for (n, m) in [
        (8u32, 2u32),
        (12, 2),
        (13, 2),
        (12, 3),
        (16, 4),
        (11, 5),
        (24, 2),
    ] {
        let centre = mesh.positions.len() as u32;
        mesh.positions.push([offset, 0.0, 0.0]);
        mesh.uvs.push([0.5, 0.5]);
        let half = n / 2;
        for i in 0..n {
            use std::f32::consts::TAU;
            let angle = TAU * i as f32 / n as f32;
            let (mut x, mut y) = (angle.cos(), angle.sin());
            if n % 2 == 0 && i >= half {
                // The exact negative of the point half a turn before.
                let earlier = TAU * (i - half) as f32 / n as f32;
                (x, y) = (-earlier.cos(), -earlier.sin());
            }
            mesh.positions.push([offset + x, y, 0.0]);
            let uv_angle = TAU * ((i * m) % n) as f32 / n as f32;
            mesh.uvs
                .push([0.5 + 0.4 * uv_angle.cos(), 0.5 + 0.4 * uv_angle.sin()]);
            mesh.indices
                .extend([centre, centre + 1 + i, centre + 1 + (i + 1) % n]);
        }
        offset += 3.0;
    }
    mesh.normals = vec![[0.0, 0.0, 1.0]; mesh.positions.len()];
    mesh
}

/// Moves `corners` random corners onto their neighbours (making degenerate triangles) and gives
/// `uvs` random vertices one UV (making triangles of zero UV area).
fn damage(mesh: &mut Mesh, corners: usize, uvs: usize, next: &mut impl FnMut() -> u32) {
    for _ in 0..corners {
        let corner = next() as usize % mesh.indices.len();
        let neighbour = (corner / 3) * 3 + (corner + 1) % 3;
        mesh.indices[corner] = mesh.indices[neighbour];
    }
    for _ in 0..uvs {
        let vertex = next() as usize % mesh.uvs.len();
        mesh.uvs[vertex] = [0.5, 0.5];
    }
}

/// A torus, the same torus with mirrored UVs, a bumpy sheet, the sheet with its triangles
/// shuffled, some corners moved onto their neighbours (degenerate triangles) and some UVs
/// collapsed, the twisted discs, and a large torus with such damage: the cases where welding,
/// grouping, sub-groups, the fallbacks and the records' layout matter.
fn meshes() -> Vec<Mesh> {
    let bumpy = |u: f32, v: f32| {
        let z = (u * 9.0).sin() * (v * 7.0).cos() * 0.2;
        let normal = [-(u * 9.0).cos() * 1.8, (v * 7.0).sin() * 1.4, 1.0];
        let length = (normal[0] * normal[0] + normal[1] * normal[1] + 1.0).sqrt();
        (
            [u, v, z],
            [normal[0] / length, normal[1] / length, 1.0 / length],
        )
    };
    let mut damaged = grid("damaged sheet", 40, 30, [3.0, 2.0], bumpy);
    let mut state = 0x2545_f491_u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    };
    let triangle_count = damaged.indices.len() / 3;
    for t in (1..triangle_count).rev() {
        let other = next() as usize % (t + 1);
        for corner in 0..3 {
            damaged.indices.swap(t * 3 + corner, other * 3 + corner);
        }
    }
    damage(&mut damaged, 60, 40, &mut next);
    // Above 2^18 triangles the records are computed per piece of vertices: a large torus in
    // its own triangle order, with degenerate triangles and collapsed UVs ("group with
    // anything" vertices, whose records the sequential pass computes again).
    let mut large = grid("large damaged torus", 400, 330, [4.0, 1.0], torus);
    damage(&mut large, 200, 150, &mut next);
    vec![
        large,
        grid("torus", 64, 32, [4.0, 1.0], torus),
        grid("mirrored torus", 64, 32, [-4.0, 1.0], torus),
        grid("bumpy sheet", 50, 50, [1.0, 1.0], bumpy),
        damaged,
        twisted_discs(),
    ]
}

#[test]
fn mikktspace_is_bit_identical_to_the_reference_wherever_the_reference_is_valid() {
    for mesh in meshes() {
        let expected = reference(&mesh);
        let input = MeshInput {
            positions: &mesh.positions,
            normals: Some(&mesh.normals),
            uvs: Some(&mesh.uvs),
            indices: Some(&mesh.indices),
        };
        for parallel in [false, true] {
            // The reference's own convention: the UV origin at the bottom left.
            let options = Options {
                uv_origin: UvOrigin::BottomLeft,
                parallel,
                ..Options::default()
            };
            let ours = generate(&input, &options)
                .expect("a well-formed mesh")
                .corner_tangents(input.indices);
            let mut compared = 0;
            for (corner, (theirs, ours)) in expected.iter().zip(&ours).enumerate() {
                let normal = mesh.normals[mesh.indices[corner] as usize];
                assert!(is_valid(*ours, normal), "{}: corner {corner}", mesh.name);
                let Some(theirs) = theirs.filter(|t| is_valid(*t, normal)) else {
                    continue;
                };
                assert_eq!(
                    theirs.map(f32::to_bits),
                    ours.map(f32::to_bits),
                    "{} (parallel: {parallel}): corner {corner}",
                    mesh.name
                );
                compared += 1;
            }
            assert!(compared * 10 > ours.len() * 9, "{}: {compared}", mesh.name);
        }
    }
}
