//! Generated test meshes whose exact tangent is known in closed form: a UV sphere and a torus.
//!
//! Shared by the benchmarks and the tests.

use std::f32::consts::PI;

/// An indexed triangle mesh with normals, one UV set and the exact tangent of every vertex
/// (`None` where it is undefined, at the sphere's poles).
pub struct Shape {
    pub name: String,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub indices: Vec<u32>,
    pub exact_tangents: Vec<Option<[f32; 3]>>,
}

impl Shape {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A UV sphere of radius 1 with `segments` around and `rings` from pole to pole. The seam and the
/// poles are split as exporters do: every pole triangle has its own pole vertex.
/// Triangles: `2 * segments * (rings - 1)`.
pub fn uv_sphere(segments: u32, rings: u32) -> Shape {
    let mut s = Shape {
        name: String::new(),
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
        exact_tangents: Vec::new(),
    };
    for ring in 0..=rings {
        let v = ring as f32 / rings as f32;
        let theta = v * PI;
        for seg in 0..=segments {
            let u = seg as f32 / segments as f32;
            let phi = u * 2.0 * PI;
            let n = [
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ];
            s.positions.push(n);
            s.normals.push(n);
            // glTF convention: v grows downwards, from the north pole.
            s.uvs.push([u, v]);
            let pole = ring == 0 || ring == rings;
            // dP/du points along increasing phi.
            s.exact_tangents.push(if pole {
                None
            } else {
                Some([-phi.sin(), 0.0, -phi.cos()])
            });
        }
    }
    let row = segments + 1;
    for ring in 0..rings {
        for seg in 0..segments {
            let a = ring * row + seg;
            let b = a + row;
            // Counter-clockwise seen from outside.
            if ring != 0 {
                s.indices.extend([a, b, a + 1]);
            }
            if ring != rings - 1 {
                s.indices.extend([a + 1, b, b + 1]);
            }
        }
    }
    s.name = format!("sphere-{}", s.triangle_count());
    s
}

/// A torus with major radius 1 and minor radius 0.3, `segments` around the axis and `sides`
/// around the tube. Triangles: `2 * segments * sides`.
pub fn torus(segments: u32, sides: u32) -> Shape {
    let (major, minor) = (1.0f32, 0.3f32);
    let mut s = Shape {
        name: String::new(),
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
        exact_tangents: Vec::new(),
    };
    for side in 0..=sides {
        let v = side as f32 / sides as f32;
        let theta = v * 2.0 * PI;
        for seg in 0..=segments {
            let u = seg as f32 / segments as f32;
            let phi = u * 2.0 * PI;
            let n = [
                theta.cos() * phi.cos(),
                theta.sin(),
                -theta.cos() * phi.sin(),
            ];
            let radius = major + minor * theta.cos();
            s.positions
                .push([radius * phi.cos(), minor * theta.sin(), -radius * phi.sin()]);
            s.normals.push(n);
            s.uvs.push([u, v]);
            s.exact_tangents.push(Some([-phi.sin(), 0.0, -phi.cos()]));
        }
    }
    let row = segments + 1;
    for side in 0..sides {
        for seg in 0..segments {
            let a = side * row + seg;
            let b = a + row;
            s.indices.extend([a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    s.name = format!("torus-{}", s.triangle_count());
    s
}

/// Sphere and torus sized to about `triangles` triangles each.
pub fn shapes_of_size(triangles: usize) -> [Shape; 2] {
    let side = ((triangles as f64 / 2.0).sqrt().round() as u32).max(3);
    [uv_sphere(side, side), torus(side, side)]
}

/// Angle in degrees between two directions, in f64. A zero or non-finite vector counts as
/// 180 degrees: a missing tangent is as wrong as one can be.
pub fn angle_degrees(a: [f32; 3], b: [f32; 3]) -> f64 {
    let a = a.map(f64::from);
    let b = b.map(f64::from);
    let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let la = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let lb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    let cos = dot / (la * lb);
    if cos.is_finite() {
        cos.clamp(-1.0, 1.0).acos().to_degrees()
    } else {
        180.0
    }
}
