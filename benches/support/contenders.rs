//! The meshes under test and the tangent generators that race on them.

pub use crate::shapes::angle_degrees;
use tspace_tangent::{self as tangent, MeshInput, Method, Options, Tangents, Weighting};

/// Where a mesh comes from; the generated ones have an exact tangent per vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    Sphere,
    Torus,
    Corpus,
}

impl Family {
    pub fn name(self) -> &'static str {
        match self {
            Family::Sphere => "sphere",
            Family::Torus => "torus",
            Family::Corpus => "corpus",
        }
    }
}

/// An indexed triangle mesh with normals and one UV set.
pub struct BenchMesh {
    pub name: String,
    pub family: Family,
    /// The size asked of the shape generator (the actual count is close to it).
    pub nominal_triangles: Option<usize>,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub indices: Vec<u32>,
    /// The exact tangent direction (dP/du) per vertex, where known and defined.
    pub exact_tangents: Option<Vec<Option<[f32; 3]>>>,
}

impl BenchMesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    fn input(&self) -> MeshInput<'_> {
        MeshInput {
            positions: &self.positions,
            normals: Some(&self.normals),
            uvs: Some(&self.uvs),
            indices: Some(&self.indices),
        }
    }
}

/// One generator with one configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Contender {
    MikkSingle,
    MikkParallel,
    FastSingle,
    FastParallel,
    FastAreaSingle,
    AxisSingle,
    Bevy,
    Meshopt,
    MeshoptCompatible,
}

impl Contender {
    pub const ALL: [Contender; 9] = [
        Contender::MikkSingle,
        Contender::MikkParallel,
        Contender::FastSingle,
        Contender::FastParallel,
        Contender::FastAreaSingle,
        Contender::AxisSingle,
        Contender::Bevy,
        Contender::Meshopt,
        Contender::MeshoptCompatible,
    ];

    /// Short name for table headers.
    pub fn label(self) -> &'static str {
        match self {
            Contender::MikkSingle => "mikk 1t",
            Contender::MikkParallel => "mikk par",
            Contender::FastSingle => "fast 1t",
            Contender::FastParallel => "fast par",
            Contender::FastAreaSingle => "fastArea",
            Contender::AxisSingle => "axis 1t",
            Contender::Bevy => "bevy",
            Contender::Meshopt => "meshopt",
            Contender::MeshoptCompatible => "mo compat",
        }
    }

    /// Name in the time-vs-error table, the CSV files and the chart legend.
    pub fn method_name(self) -> &'static str {
        match self {
            Contender::MikkSingle => "tspace mikktspace",
            Contender::MikkParallel => "tspace mikktspace (parallel)",
            Contender::FastSingle => "tspace fast (angle)",
            Contender::FastParallel => "tspace fast (angle, parallel)",
            Contender::FastAreaSingle => "tspace fast (area)",
            Contender::AxisSingle => "tspace axis",
            Contender::Bevy => "bevy_mikktspace",
            Contender::Meshopt => "meshopt default",
            Contender::MeshoptCompatible => "meshopt Compatible",
        }
    }

    /// Whether it spreads its work over rayon's pool.
    pub fn is_parallel(self) -> bool {
        matches!(self, Contender::MikkParallel | Contender::FastParallel)
    }

    /// Whether its heap use can be measured: meshoptimizer allocates through C++ `new`, which
    /// the Rust global allocator never sees.
    pub fn heap_is_visible(self) -> bool {
        !matches!(self, Contender::Meshopt | Contender::MeshoptCompatible)
    }

    fn tspace_options(self) -> Option<Options> {
        let (method, weighting, parallel) = match self {
            Contender::MikkSingle => (Method::MikkTSpace, Weighting::Angle, false),
            Contender::MikkParallel => (Method::MikkTSpace, Weighting::Angle, true),
            Contender::FastSingle => (Method::Fast, Weighting::Angle, false),
            Contender::FastParallel => (Method::Fast, Weighting::Angle, true),
            Contender::FastAreaSingle => (Method::Fast, Weighting::Area, false),
            Contender::AxisSingle => (Method::Axis, Weighting::Angle, false),
            Contender::Bevy | Contender::Meshopt | Contender::MeshoptCompatible => return None,
        };
        // The default UV origin (glTF's top left) only negates `w`; every contender is timed
        // with the options a glTF pipeline would use.
        Some(Options {
            method,
            weighting,
            parallel,
            ..Options::default()
        })
    }
}

/// What a contender returns. Kept whole so that dropping it stays outside the timed region.
pub enum Output {
    /// Boxed because `Tangents` carries its diagnostics inline; the box is one small allocation
    /// next to the multi-megabyte vectors.
    Tspace(Box<Tangents>),
    Corners(Vec<[f32; 4]>),
}

impl Output {
    /// One tangent per corner (per index) of `mesh`, `xyz` and the sign in `w`.
    pub fn corners(&self, mesh: &BenchMesh) -> std::borrow::Cow<'_, [[f32; 4]]> {
        match self {
            Output::Tspace(t) => std::borrow::Cow::Owned(t.corner_tangents(Some(&mesh.indices))),
            Output::Corners(c) => std::borrow::Cow::Borrowed(c),
        }
    }
}

/// Runs one contender once. Errors are the generator's own (invalid input), as text.
pub fn run(contender: Contender, mesh: &BenchMesh) -> Result<Output, String> {
    if let Some(options) = contender.tspace_options() {
        return tangent::generate(&mesh.input(), &options)
            .map(|t| Output::Tspace(Box::new(t)))
            .map_err(|e| e.to_string());
    }
    match contender {
        Contender::Bevy => bevy_tangents(mesh).map(Output::Corners),
        Contender::Meshopt | Contender::MeshoptCompatible => {
            let options = if contender == Contender::Meshopt {
                meshopt::TangentOptions::None
            } else {
                meshopt::TangentOptions::Compatible
            };
            Ok(Output::Corners(meshopt::generate_tangents(
                Some(&mesh.indices),
                &mesh.positions,
                &mesh.normals,
                &mesh.uvs,
                options,
            )))
        }
        _ => unreachable!("every tspace contender has options"),
    }
}

/// bevy_mikktspace through its `Geometry` trait, the way a caller with indexed arrays uses it
/// (the test kit's oracle). Corners it leaves without a tangent stay zero.
fn bevy_tangents(mesh: &BenchMesh) -> Result<Vec<[f32; 4]>, String> {
    let tangents = tspace_testkit::reference_tangents(
        &mesh.positions,
        &mesh.normals,
        &mesh.uvs,
        &mesh.indices,
    );
    Ok(tangents
        .into_iter()
        .map(|t| t.unwrap_or([0.0; 4]))
        .collect())
}

/// Angular error statistics over corners, in degrees.
#[derive(Clone, Copy, Debug)]
pub struct ErrorStats {
    pub mean: f64,
    pub p99: f64,
    pub max: f64,
    pub corners: usize,
}

/// Compares each corner's tangent direction with the exact tangent of its vertex. Corners whose
/// exact tangent is undefined (the sphere's poles) are skipped. `w` is not compared: the
/// exact tangent is a direction only, and the UV origin convention only changes `w`.
pub fn error_against_exact(
    corners: &[[f32; 4]],
    indices: &[u32],
    exact: &[Option<[f32; 3]>],
) -> Option<ErrorStats> {
    let mut angles: Vec<f64> = corners
        .iter()
        .zip(indices)
        .filter_map(|(t, &v)| {
            let e = exact.get(v as usize).copied().flatten()?;
            Some(angle_degrees([t[0], t[1], t[2]], e))
        })
        .collect();
    if angles.is_empty() {
        return None;
    }
    let count = angles.len();
    let mean = angles.iter().sum::<f64>() / count as f64;
    let max = angles.iter().copied().fold(0.0, f64::max);
    // Nearest-rank percentile.
    let rank = ((count as f64 * 0.99).ceil() as usize).clamp(1, count) - 1;
    let (_, p99, _) = angles.select_nth_unstable_by(rank, f64::total_cmp);
    Some(ErrorStats {
        mean,
        p99: *p99,
        max,
        corners: count,
    })
}

/// The largest angle (degrees) between corresponding corner tangents, and the share of corners
/// more than 0.01° apart, over the corners the reference gave a tangent (nonzero xyz).
pub fn deviation(ours: &[[f32; 4]], reference: &[[f32; 4]]) -> (f64, f64) {
    let mut max = 0.0f64;
    let (mut compared, mut beyond) = (0usize, 0usize);
    for (o, r) in ours.iter().zip(reference) {
        if r[..3].iter().all(|&x| x == 0.0) {
            continue;
        }
        let angle = angle_degrees([o[0], o[1], o[2]], [r[0], r[1], r[2]]);
        max = max.max(angle);
        compared += 1;
        beyond += usize::from(angle > 0.01);
    }
    (max, beyond as f64 / compared.max(1) as f64)
}
