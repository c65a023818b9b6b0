//! Random meshes for the property tests: mostly-sensible surfaces and chaotic triangle soups,
//! damaged with degenerate triangles, slivers, non-finite values, odd normals and odd UVs.
//!
//! Everything is built from proptest strategies (not from a seed) so that failures shrink.

use proptest::prelude::*;
use proptest::sample::Index;
use tspace_tangent::MeshInput;

/// An owned triangle list, indexed or not.
#[derive(Clone, Debug, PartialEq)]
pub struct RandomMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
    pub indices: Option<Vec<u32>>,
}

impl RandomMesh {
    pub fn input(&self) -> MeshInput<'_> {
        MeshInput {
            positions: &self.positions,
            normals: self.normals.as_deref(),
            uvs: self.uvs.as_deref(),
            indices: self.indices.as_deref(),
        }
    }

    pub fn corner_count(&self) -> usize {
        self.indices.as_ref().map_or(self.positions.len(), Vec::len)
    }

    /// The input vertex of corner `c`.
    pub fn vertex_of_corner(&self, c: usize) -> usize {
        self.indices.as_ref().map_or(c, |i| i[c] as usize)
    }

    /// The three input vertices of the triangle holding corner `c`.
    pub fn triangle_of_corner(&self, c: usize) -> [usize; 3] {
        let base = c - c % 3;
        [
            self.vertex_of_corner(base),
            self.vertex_of_corner(base + 1),
            self.vertex_of_corner(base + 2),
        ]
    }

    /// The same triangles with one vertex per corner.
    pub fn unindexed(&self) -> RandomMesh {
        let Some(indices) = &self.indices else {
            return self.clone();
        };
        let pick3 = |v: &Vec<[f32; 3]>| indices.iter().map(|&i| v[i as usize]).collect();
        RandomMesh {
            positions: pick3(&self.positions),
            normals: self.normals.as_ref().map(pick3),
            uvs: self
                .uvs
                .as_ref()
                .map(|uvs| indices.iter().map(|&i| uvs[i as usize]).collect()),
            indices: None,
        }
    }
}

/// Where the mesh sits in space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Placement {
    AsIs,
    /// Every coordinate offset by about 1e7 (the float spacing there is 1).
    Offset,
    /// Every coordinate scaled by 1e-7.
    Tiny,
    /// Scaled by 1e-7, then offset by 1e3 (spacing 6e-5: most of the mesh collapses).
    TinyOffset,
}

impl Placement {
    fn apply(self, p: [f32; 3]) -> [f32; 3] {
        match self {
            Placement::AsIs => p,
            Placement::Offset => [p[0] + 1.0e7, p[1] - 1.0e7, p[2] + 3.0e7],
            Placement::Tiny => p.map(|x| x * 1.0e-7),
            Placement::TinyOffset => p.map(|x| x * 1.0e-7 + 1.0e3),
        }
    }
}

pub fn placement() -> impl Strategy<Value = Placement> {
    prop_oneof![
        6 => Just(Placement::AsIs),
        2 => Just(Placement::Offset),
        2 => Just(Placement::Tiny),
        1 => Just(Placement::TinyOffset),
    ]
}

pub fn non_finite() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(-f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
    ]
}

/// A coordinate: lattice values (exact duplicates, collinear and coplanar triangles), random
/// values, signed zeros, extreme magnitudes and, rarely, NaN or infinity.
pub fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        20 => (-4i32..=4).prop_map(|k| k as f32 * 0.5),
        20 => -1.0f32..1.0,
        2 => Just(-0.0f32),
        2 => prop_oneof![
            Just(1.0e-20f32),
            Just(-3.0e-30),
            Just(1.0e-40),
            Just(2.0e19),
            Just(-1.0e30),
        ],
        1 => non_finite(),
    ]
}

fn unit_direction() -> impl Strategy<Value = [f32; 3]> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(|(x, y, z)| {
        let len = (x * x + y * y + z * z).sqrt();
        if len > 1e-3 {
            [x / len, y / len, z / len]
        } else {
            [0.0, 0.0, 1.0]
        }
    })
}

fn axis_direction() -> impl Strategy<Value = [f32; 3]> {
    (0usize..3, any::<bool>()).prop_map(|(axis, negative)| {
        let mut n = [0.0; 3];
        n[axis] = if negative { -1.0 } else { 1.0 };
        n
    })
}

/// A normal: mostly unit, sometimes zero, non-unit (from 1e-39 to 1e20 long) or not finite.
pub fn normal() -> impl Strategy<Value = [f32; 3]> {
    prop_oneof![
        16 => unit_direction(),
        6 => axis_direction(),
        2 => Just([0.0f32, 0.0, 0.0]),
        1 => Just([-0.0f32, 0.0, -0.0]),
        6 => (
            unit_direction(),
            prop_oneof![
                Just(0.5f32),
                Just(3.0),
                Just(1.0e-3),
                Just(1.0e3),
                Just(1.0e-20),
                Just(1.0e-30),
                Just(1.0e-39),
                Just(1.0e20),
                Just(1.0e30),
            ],
        )
            .prop_map(|(n, s)| n.map(|x| x * s)),
        1 => (unit_direction(), 0usize..3, non_finite()).prop_map(|(mut n, i, x)| {
            n[i] = x;
            n
        }),
    ]
}

/// A texture coordinate: lattice values (zero UV area, overlaps), random values, rarely huge or
/// not finite.
pub fn uv() -> impl Strategy<Value = [f32; 2]> {
    let component = prop_oneof![
        20 => (-4i32..=8).prop_map(|k| k as f32 * 0.25),
        20 => -1.0f32..2.0,
        1 => prop_oneof![Just(1.0e20f32), Just(-1.0e-30), Just(1.0e30)],
        1 => non_finite(),
    ];
    [component.clone(), component]
}

/// A triangle soup over a small vertex pool (many shared and non-manifold edges).
pub fn chaotic() -> impl Strategy<Value = RandomMesh> {
    (
        proptest::collection::vec((coordinate(), coordinate(), coordinate()), 3..16),
        proptest::collection::vec((any::<Index>(), any::<Index>(), any::<Index>()), 0..20),
    )
        .prop_flat_map(|(positions, triangles)| {
            let n = positions.len();
            (
                Just(positions),
                Just(triangles),
                proptest::collection::vec(normal(), n),
                proptest::collection::vec(uv(), n),
            )
        })
        .prop_map(|(positions, triangles, normals, uvs)| {
            let n = positions.len();
            let indices = triangles
                .iter()
                .flat_map(|(a, b, c)| [a.index(n), b.index(n), c.index(n)])
                .map(|i| i as u32)
                .collect();
            RandomMesh {
                positions: positions.into_iter().map(|(x, y, z)| [x, y, z]).collect(),
                normals: Some(normals),
                uvs: Some(uvs),
                indices: Some(indices),
            }
        })
}

/// How a grid is texture-mapped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UvLayout {
    Planar,
    /// `v` grows the other way (origin convention flipped).
    FlippedV,
    /// The right half mirrored onto the left (a mirror seam down the middle).
    MirroredHalf,
    /// Every cell maps onto the same unit square (overlapping, alternating orientation).
    Overlapping,
    /// `u` and `v` swapped.
    Swapped,
    /// Everything on one point (zero UV area everywhere).
    Constant,
    /// Every row on one line (zero UV area, non-zero derivative).
    Collapsed,
}

fn uv_layout() -> impl Strategy<Value = UvLayout> {
    prop_oneof![
        3 => Just(UvLayout::Planar),
        1 => Just(UvLayout::FlippedV),
        3 => Just(UvLayout::MirroredHalf),
        2 => Just(UvLayout::Overlapping),
        1 => Just(UvLayout::Swapped),
        1 => Just(UvLayout::Constant),
        1 => Just(UvLayout::Collapsed),
    ]
}

/// How a grid's normals are set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NormalLayout {
    /// +Z everywhere (the grid is a height field, so roughly right).
    Up,
    /// -Z everywhere (opposite to the winding).
    Down,
    /// Random per vertex.
    Random,
}

fn normal_layout() -> impl Strategy<Value = NormalLayout> {
    prop_oneof![
        4 => Just(NormalLayout::Up),
        1 => Just(NormalLayout::Down),
        2 => Just(NormalLayout::Random),
    ]
}

/// Local damage applied to a mesh.
#[derive(Clone, Debug)]
pub enum Damage {
    /// One coordinate of a vertex becomes NaN or infinite.
    PositionNonFinite(Index, usize, f32),
    /// A vertex moves onto another one's position (repeated position).
    CopyPosition(Index, Index),
    /// A vertex gets another normal (zero, non-unit, non-finite...).
    Normal(Index, [f32; 3]),
    /// A vertex gets another texture coordinate.
    Uv(Index, [f32; 2]),
    /// One corner of a triangle takes the vertex of another of its corners (repeated vertex).
    RepeatVertex(Index, usize),
    /// A new vertex on the segment between two vertices, at `t` along it, plus a triangle using
    /// both ends and it (collinear, or a sliver after rounding).
    Collinear(Index, Index, f32),
    /// A new vertex a tiny distance off a vertex, plus a sliver triangle.
    Sliver(Index, Index, f32),
    /// An extra triangle over existing vertices (overlaps, non-manifold edges).
    Triangle(Index, Index, Index),
    /// A triangle duplicated, possibly reversed.
    Duplicate(Index, bool),
    /// A vertex no triangle uses.
    Unused([f32; 3], [f32; 3], [f32; 2]),
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        1 => (any::<Index>(), 0usize..3, non_finite())
            .prop_map(|(v, i, x)| Damage::PositionNonFinite(v, i, x)),
        2 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Damage::CopyPosition(a, b)),
        3 => (any::<Index>(), normal()).prop_map(|(v, n)| Damage::Normal(v, n)),
        2 => (any::<Index>(), uv()).prop_map(|(v, t)| Damage::Uv(v, t)),
        2 => (any::<Index>(), 0usize..3).prop_map(|(t, i)| Damage::RepeatVertex(t, i)),
        2 => (any::<Index>(), any::<Index>(), prop_oneof![Just(0.5f32), 0.0f32..1.0])
            .prop_map(|(a, b, t)| Damage::Collinear(a, b, t)),
        2 => (
            any::<Index>(),
            any::<Index>(),
            prop_oneof![Just(1.0e-6f32), Just(1.0e-3), Just(1.0e-9)]
        )
            .prop_map(|(a, b, e)| Damage::Sliver(a, b, e)),
        2 => (any::<Index>(), any::<Index>(), any::<Index>())
            .prop_map(|(a, b, c)| Damage::Triangle(a, b, c)),
        1 => (any::<Index>(), any::<bool>()).prop_map(|(t, r)| Damage::Duplicate(t, r)),
        1 => (
            (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| [x, y, z]),
            normal(),
            uv()
        )
            .prop_map(|(p, n, t)| Damage::Unused(p, n, t)),
    ]
}

/// A height-field grid of `w` × `h` vertices with consistent normals and one of several UV
/// layouts.
pub fn grid(max_side: usize) -> impl Strategy<Value = RandomMesh> {
    (2..=max_side, 2..=max_side, uv_layout(), normal_layout())
        .prop_flat_map(|(w, h, layout, normals)| {
            (
                Just((w, h, layout, normals)),
                proptest::collection::vec(prop_oneof![3 => Just(0.0f32), 1 => -0.3f32..0.3], w * h),
                proptest::collection::vec(any::<bool>(), (w - 1) * (h - 1)),
                proptest::collection::vec(normal(), w * h),
            )
        })
        .prop_map(
            |((w, h, layout, normal_layout), heights, diagonals, random)| {
                let mut positions = Vec::with_capacity(w * h);
                let mut uvs = Vec::with_capacity(w * h);
                let mut normals = Vec::with_capacity(w * h);
                for j in 0..h {
                    for i in 0..w {
                        let (x, y) = (i as f32, j as f32);
                        positions.push([x, y, heights[j * w + i]]);
                        let (u, v) = (x / (w - 1) as f32, y / (h - 1) as f32);
                        uvs.push(match layout {
                            UvLayout::Planar => [u, v],
                            UvLayout::FlippedV => [u, 1.0 - v],
                            UvLayout::MirroredHalf => [(2.0 * u - 1.0).abs(), v],
                            UvLayout::Overlapping => [(i % 2) as f32, (j % 2) as f32],
                            UvLayout::Swapped => [v, u],
                            UvLayout::Constant => [0.25, 0.75],
                            UvLayout::Collapsed => [u, 0.5],
                        });
                        normals.push(match normal_layout {
                            NormalLayout::Up => [0.0, 0.0, 1.0],
                            NormalLayout::Down => [0.0, 0.0, -1.0],
                            NormalLayout::Random => random[j * w + i],
                        });
                    }
                }
                let mut indices = Vec::with_capacity(6 * diagonals.len());
                for j in 0..h - 1 {
                    for i in 0..w - 1 {
                        let a = (j * w + i) as u32;
                        let (b, c, d) = (a + 1, a + w as u32 + 1, a + w as u32);
                        if diagonals[j * (w - 1) + i] {
                            indices.extend([a, b, c, a, c, d]);
                        } else {
                            indices.extend([a, b, d, b, c, d]);
                        }
                    }
                }
                RandomMesh {
                    positions,
                    normals: Some(normals),
                    uvs: Some(uvs),
                    indices: Some(indices),
                }
            },
        )
}

/// Applies damage to an indexed mesh that has normals and UVs.
pub fn apply_damage(mesh: &mut RandomMesh, damage: &[Damage]) {
    for d in damage {
        let n = mesh.positions.len();
        let triangle_count = mesh.indices.as_ref().map_or(0, |i| i.len() / 3);
        let normals = mesh.normals.as_mut().expect("damage needs normals");
        let uvs = mesh.uvs.as_mut().expect("damage needs uvs");
        let indices = mesh.indices.as_mut().expect("damage needs indices");
        match d {
            Damage::PositionNonFinite(v, i, x) => mesh.positions[v.index(n)][*i] = *x,
            Damage::CopyPosition(from, to) => {
                mesh.positions[to.index(n)] = mesh.positions[from.index(n)];
            }
            Damage::Normal(v, value) => normals[v.index(n)] = *value,
            Damage::Uv(v, value) => uvs[v.index(n)] = *value,
            Damage::RepeatVertex(t, i) => {
                if triangle_count > 0 {
                    let base = 3 * t.index(triangle_count);
                    indices[base + i] = indices[base + (i + 1) % 3];
                }
            }
            Damage::Collinear(a, b, t) => {
                let (a, b) = (a.index(n), b.index(n));
                let (pa, pb) = (mesh.positions[a], mesh.positions[b]);
                let p = [0, 1, 2].map(|k| pa[k] + (pb[k] - pa[k]) * t);
                let (ua, ub) = (uvs[a], uvs[b]);
                mesh.positions.push(p);
                normals.push(normals[a]);
                // Off the UV segment, so the triangle has UV area but no position area.
                uvs.push([ua[0] + (ub[0] - ua[0]) * t, ua[1] + 0.5]);
                indices.extend([a as u32, b as u32, n as u32]);
            }
            Damage::Sliver(a, b, eps) => {
                let (a, b) = (a.index(n), b.index(n));
                let pa = mesh.positions[a];
                let p = [pa[0] + eps, pa[1] - eps * 0.5, pa[2] + eps * 0.25];
                mesh.positions.push(p);
                normals.push(normals[a]);
                uvs.push([uvs[a][0] + 0.1, uvs[a][1] - 0.2]);
                indices.extend([a as u32, b as u32, n as u32]);
            }
            Damage::Triangle(a, b, c) => {
                indices.extend([a.index(n) as u32, b.index(n) as u32, c.index(n) as u32]);
            }
            Damage::Duplicate(t, reversed) => {
                if triangle_count > 0 {
                    let base = 3 * t.index(triangle_count);
                    let mut tri = [indices[base], indices[base + 1], indices[base + 2]];
                    if *reversed {
                        tri.swap(1, 2);
                    }
                    indices.extend(tri);
                }
            }
            Damage::Unused(p, nn, t) => {
                mesh.positions.push(*p);
                normals.push(*nn);
                uvs.push(*t);
            }
        }
    }
}

/// What the core is given, besides the triangles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    pub placement: Placement,
    pub indexed: bool,
    pub with_normals: bool,
    pub with_uvs: bool,
}

pub fn layout() -> impl Strategy<Value = Layout> {
    (
        placement(),
        prop::bool::weighted(0.75),
        prop::bool::weighted(0.7),
        prop::bool::weighted(0.9),
    )
        .prop_map(|(placement, indexed, with_normals, with_uvs)| Layout {
            placement,
            indexed,
            with_normals,
            with_uvs,
        })
}

pub fn finish(mut mesh: RandomMesh, layout: Layout) -> RandomMesh {
    for p in &mut mesh.positions {
        *p = layout.placement.apply(*p);
    }
    if !layout.indexed {
        mesh = mesh.unindexed();
    }
    if !layout.with_normals {
        mesh.normals = None;
    }
    if !layout.with_uvs {
        mesh.uvs = None;
    }
    mesh
}

/// Any mesh of the mix: a damaged grid or a chaotic soup, in any layout.
pub fn any_mesh() -> impl Strategy<Value = RandomMesh> {
    any_mesh_in(layout())
}

/// An indexed mesh with normals and texture coordinates, anywhere.
pub fn full_indexed_mesh() -> impl Strategy<Value = RandomMesh> {
    any_mesh_in(placement().prop_map(|placement| Layout {
        placement,
        indexed: true,
        with_normals: true,
        with_uvs: true,
    }))
}

/// A damaged grid or a chaotic soup, in the given layouts.
pub fn any_mesh_in(layout: impl Strategy<Value = Layout>) -> impl Strategy<Value = RandomMesh> {
    let damaged_grid =
        (grid(5), proptest::collection::vec(damage(), 0..6)).prop_map(|(mut mesh, damage)| {
            apply_damage(&mut mesh, &damage);
            mesh
        });
    (prop_oneof![3 => damaged_grid, 2 => chaotic()], layout)
        .prop_map(|(mesh, layout)| finish(mesh, layout))
}
