//! glTF 2.0: the GLB container, the accessor decoder, the lossless JSON reader and splice
//! editor, and [`process`], which puts them together: load, decide, compute once per distinct
//! geometry, write back only what changed, and report.

pub mod accessor;
pub mod compute;
pub mod glb;

pub mod load;

pub mod plan;
pub mod refs;
pub mod write;

use crate::scene::error::SceneError;
use crate::scene::report::{MorphReport, PrimitiveReport, Report};
use compute::{Computed, GeometryLimits};
use load::{LoadLimits, Resources};
use plan::{Action, GeometryKey, PlanOptions, Topology};
use rayon::prelude::*;
use std::collections::HashMap;
use tspace_json::Node;
use tspace_tangent::{Method, NormalMode, Options, UvOrigin};
use write::{Changes, OutputFormat, PrimitiveEdit, Ref};

/// Caps on what one scene may make tspace allocate or compute.
#[derive(Clone, Copy, Debug)]
pub struct SceneLimits {
    /// Triangles over all distinct computations of one scene.
    pub max_triangles: usize,
    /// Elements in one accessor.
    pub max_vertices: usize,
    /// Bytes one buffer may declare.
    pub max_buffer_bytes: usize,
}

impl Default for SceneLimits {
    fn default() -> Self {
        SceneLimits {
            max_triangles: 1 << 24,
            max_vertices: 1 << 24,
            max_buffer_bytes: 1 << 30,
        }
    }
}

/// What to do with a scene.
#[derive(Clone, Copy, Debug)]
pub struct SceneOptions {
    pub method: Method,
    /// Recompute tangents a primitive already has.
    pub overwrite: bool,
    /// Give tangents to every triangle primitive, whatever its material.
    pub all: bool,
    pub format: OutputFormat,
    /// For primitives without normals.
    pub normal_mode: NormalMode,
    /// Write the scene; `false` only analyses and reports.
    pub write: bool,
    pub limits: SceneLimits,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            method: Method::MikkTSpace,
            overwrite: false,
            all: false,
            format: OutputFormat::Glb,
            normal_mode: NormalMode::Flat,
            write: true,
            limits: SceneLimits::default(),
        }
    }
}

/// The written scene (unless only analysed) and its report.
pub struct Processed {
    pub bytes: Option<Vec<u8>>,
    pub report: Report,
}

fn accessor_count(root: &Node, index: Option<usize>) -> usize {
    index
        .and_then(|i| root.get("accessors")?.index(i)?.get("count")?.as_u64())
        .and_then(|n| usize::try_from(n).ok())
        .unwrap_or(0)
}

fn extension_listed(root: &Node, list: &str, name: &str) -> bool {
    root.get(list)
        .and_then(Node::as_array)
        .unwrap_or(&[])
        .iter()
        .any(|e| e.as_str() == Some(name))
}

fn primitive_node(root: &Node, mesh: usize, primitive: usize) -> Option<&Node> {
    root.get("meshes")?
        .index(mesh)?
        .get("primitives")?
        .index(primitive)
}

/// Processes a GLB or `.gltf`. `resources` supplies what relative URIs name (buffers, and for
/// GLB output the images to embed).
pub fn process<'a>(
    bytes: &'a [u8],
    resources: &dyn Resources<'a>,
    options: &SceneOptions,
) -> Result<Processed, SceneError> {
    process_with(bytes, resources, options, &Internal::default())
}

/// Choices that depend on where the scene came from, not on the caller's options.
#[derive(Clone, Copy, Debug, Default)]
pub struct Internal {
    /// Give tangents to primitives without a material (a converted OBJ without MTL).
    pub no_material_means_tangents: bool,
}

/// [`process`], with the choices of [`Internal`].
pub fn process_with<'a>(
    bytes: &'a [u8],
    resources: &dyn Resources<'a>,
    options: &SceneOptions,
    internal: &Internal,
) -> Result<Processed, SceneError> {
    let limits = options.limits;
    let loaded = load::load(
        bytes,
        resources,
        &LoadLimits {
            max_buffer_bytes: limits.max_buffer_bytes,
        },
    )?;
    let root = loaded.doc.root();
    if extension_listed(root, "extensionsRequired", "KHR_draco_mesh_compression") {
        return Err(SceneError::unprocessable(
            "draco-required",
            "the file requires KHR_draco_mesh_compression, which tspace does not decode; export it without Draco, or with an uncompressed fallback",
        ));
    }

    let plans = plan::plan(
        root,
        &PlanOptions {
            overwrite: options.overwrite,
            all: options.all,
            axis: options.method == Method::Axis,
            no_material_means_tangents: internal.no_material_means_tangents,
        },
    );

    // One job per distinct geometry and method; audits always compare with MikkTSpace.
    let mut job_of_plan: Vec<Option<usize>> = vec![None; plans.len()];
    let mut jobs: Vec<(GeometryKey, Method, String)> = Vec::new();
    let mut job_index: HashMap<(GeometryKey, Method), usize> = HashMap::new();
    let mut triangles_planned = 0usize;
    for (p, plan) in plans.iter().enumerate() {
        let Some(key) = &plan.key else { continue };
        let method = match plan.action {
            Action::Audit => Method::MikkTSpace,
            _ => options.method,
        };
        let path = format!("meshes[{}].primitives[{}]", plan.mesh, plan.primitive);
        if let Some(primitive) = primitive_node(root, plan.mesh, plan.primitive) {
            let draco = primitive
                .get("extensions")
                .and_then(|e| e.get("KHR_draco_mesh_compression"))
                .is_some();
            let position_has_data = root
                .get("accessors")
                .and_then(|a| a.index(key.position))
                .is_some_and(|a| a.get("bufferView").is_some() || a.get("sparse").is_some());
            if draco && !position_has_data {
                return Err(SceneError::unprocessable(
                    "draco-required",
                    format!(
                        "{path} is compressed with KHR_draco_mesh_compression and has no uncompressed fallback; tspace does not decode Draco"
                    ),
                ));
            }
        }
        let next = jobs.len();
        let job = *job_index
            .entry((key.clone(), method))
            .or_insert_with(|| next);
        if job == next {
            let corners = match key.indices {
                Some(_) => accessor_count(root, key.indices),
                None => accessor_count(root, Some(key.position)),
            };
            let per_target = 1 + key.targets.len();
            triangles_planned = triangles_planned.saturating_add(corners / 3 * per_target);
            jobs.push((key.clone(), method, path));
        }
        job_of_plan[p] = Some(job);
    }
    if triangles_planned > limits.max_triangles {
        return Err(SceneError::too_large(
            "too-many-triangles",
            format!(
                "the scene needs tangents for {triangles_planned} triangles (morph targets included); the limit is {}",
                limits.max_triangles
            ),
        ));
    }

    let buffer_slices = loaded.buffer_slices();
    let geometry_limits = GeometryLimits {
        max_vertices: limits.max_vertices,
        max_triangles: limits.max_triangles,
    };
    let results: Vec<Result<Computed, SceneError>> = jobs
        .par_iter()
        .map(|(key, method, path)| {
            let large = accessor_count(root, key.indices.or(Some(key.position))) > 300_000;
            let core_options = Options {
                method: *method,
                uv_origin: UvOrigin::TopLeft,
                normal_mode: options.normal_mode,
                parallel: large,
                ..Options::default()
            };
            compute::compute(
                root,
                key,
                &buffer_slices,
                &core_options,
                &geometry_limits,
                path,
            )
        })
        .collect();
    let mut computed = Vec::with_capacity(results.len());
    for result in results {
        computed.push(result?);
    }

    let mut report = Report {
        tspace_version: env!("CARGO_PKG_VERSION"),
        input_format: match loaded.container {
            load::Container::Glb => "glb",
            load::Container::Json => "gltf",
        },
        input_bytes: bytes.len() as u64
            + loaded
                .buffers
                .iter()
                .filter(|b| matches!(b.source, load::BufferSource::External(_)))
                .map(|b| b.bytes.len() as u64)
                .sum::<u64>(),
        method: options.method.name(),
        overwrite: options.overwrite,
        all: options.all,
        ..Report::default()
    };
    report.primitives.reserve_exact(plans.len());
    let mut changes = Changes::default();
    let mut job_refs: HashMap<usize, JobRefs> = HashMap::new();
    let mut remapped: HashMap<(usize, usize), Ref> = HashMap::new();
    let mut first_plan_of_job: HashMap<usize, [usize; 2]> = HashMap::new();
    for (p, plan) in plans.iter().enumerate() {
        let mut entry = PrimitiveReport {
            mesh: plan.mesh,
            primitive: plan.primitive,
            mesh_name: plan.mesh_name.clone(),
            material: plan.material,
            uses: plan.uses,
            texcoord: plan.texcoord_set,
            notes: plan.notes.clone(),
            ..PrimitiveReport::default()
        };
        report.summary.primitives += 1;
        let job = job_of_plan[p];
        let here = [plan.mesh, plan.primitive];
        let shared_with = job.map(|j| *first_plan_of_job.entry(j).or_insert(here));
        entry.shared_with = shared_with.filter(|first| *first != here);
        match (
            &plan.action,
            job.and_then(|j| computed.get(j).map(|c| (j, c))),
        ) {
            (Action::Skip(reason), _) => {
                report.summary.skipped += 1;
                entry.action = "skipped";
                entry.reason = Some(reason.code());
                entry.message = Some(reason.message());
            }
            (Action::Audit, Some((_, c))) => {
                report.summary.audited += 1;
                entry.action = "audited";
                let tangent = primitive_node(root, plan.mesh, plan.primitive)
                    .and_then(|n| n.get("attributes")?.get("TANGENT")?.as_u64())
                    .and_then(|i| usize::try_from(i).ok());
                if let Some(index) = tangent {
                    let described = accessor::accessor_from_json(root, index, &buffer_slices)
                        .map_err(compute::accessor_error)?;
                    let existing = accessor::read_floats::<4>(&described, limits.max_vertices)
                        .map_err(compute::accessor_error)?;
                    let quantized = described.component_type != accessor::ComponentType::F32;
                    match compute::audit(&existing, c, quantized) {
                        Ok(audit) => {
                            if audit.verdict != "matches" {
                                report.summary.audits_disagreeing += 1;
                            }
                            entry.audit = Some(Box::new(audit));
                        }
                        Err(problem) => entry.notes.push(format!("audit not possible: {problem}")),
                    }
                }
                // Primitives that share a computation share its diagnostics: the report
                // gives them once, on the first, or a scene of many copies would grow huge.
                if entry.shared_with.is_none() {
                    entry.diagnostics = Some(Box::new((&c.tangents.diagnostics).into()));
                }
            }
            (Action::Generate, Some((j, c))) => {
                report.summary.generated += 1;
                entry.action = if plan.had_tangents {
                    "overwritten"
                } else {
                    "generated"
                };
                // Primitives that share a computation share its diagnostics: the report
                // gives them once, on the first, or a scene of many copies would grow huge.
                if entry.shared_with.is_none() {
                    entry.diagnostics = Some(Box::new((&c.tangents.diagnostics).into()));
                }
                let Some(key) = &plan.key else { continue };
                let Some(primitive) = primitive_node(root, plan.mesh, plan.primitive) else {
                    continue;
                };
                let edit = edit_primitive(
                    root,
                    primitive,
                    key.topology,
                    j,
                    c,
                    &buffer_slices,
                    limits.max_vertices,
                    &mut changes,
                    &mut job_refs,
                    &mut remapped,
                )?;
                if !key.targets.is_empty() {
                    entry.morph_targets = Some(Box::new(MorphReport {
                        targets: key.targets.len() as u64,
                        with_tangent_deltas: c.target_deltas.iter().filter(|d| d.is_some()).count()
                            as u64,
                        handedness_changes: c.morph_handedness_changes,
                    }));
                }
                changes.primitives.insert((plan.mesh, plan.primitive), edit);
            }
            _ => {
                entry.action = "skipped";
            }
        }
        report.primitives.push(entry);
    }
    report.summary.computations = computed.len() as u64;
    for c in &computed {
        let d = &c.tangents.diagnostics;
        report.summary.triangles += d.triangles;
        report.summary.fallback_tangents += d.fallback_tangents.corners.count;
        report.summary.handedness_flip_vertices += d.handedness_flip_vertices.count;
        report.summary.degenerate_triangles +=
            d.duplicate_position_triangles.count + d.zero_area_triangles.count;
        report.summary.mirrored_uv_triangles += d.mirrored_uv_triangles.count;
    }
    for (j, c) in computed.iter().enumerate() {
        if job_refs.contains_key(&j) {
            report.summary.vertices_added += c.tangents.diagnostics.vertices_added;
        }
    }

    let bytes_out = if !options.write {
        None
    } else if changes.primitives.is_empty()
        && loaded.container == load::Container::Glb
        && options.format == OutputFormat::Glb
    {
        // Nothing to change: the input is the output, byte for byte.
        Some(bytes.to_vec())
    } else {
        let written = write::write(&loaded, &changes, options.format, resources)?;
        report.input_bytes += written.embedded_image_bytes;
        report.dropped = written.dropped;
        report.warnings.extend(written.warnings);
        Some(written.bytes)
    };
    if let Some(out) = &bytes_out {
        report.output_format = Some(options.format.name());
        report.output_bytes = Some(out.len() as u64);
    }
    Ok(Processed {
        bytes: bytes_out,
        report,
    })
}

/// The accessors one computation adds, shared by every primitive that uses it.
#[derive(Default)]
struct JobRefs {
    tangent: Option<Ref>,
    normal: Option<Ref>,
    indices: Option<Ref>,
    deltas: HashMap<usize, Ref>,
}

#[allow(clippy::too_many_arguments)]
fn edit_primitive(
    root: &Node,
    primitive: &Node,
    topology: Topology,
    job: usize,
    c: &Computed,
    buffers: &[&[u8]],
    max_vertices: usize,
    changes: &mut Changes,
    job_refs: &mut HashMap<usize, JobRefs>,
    remapped: &mut HashMap<(usize, usize), Ref>,
) -> Result<PrimitiveEdit, SceneError> {
    let refs = job_refs.entry(job).or_default();
    let split = &c.tangents.split;
    let tangent = *refs
        .tangent
        .get_or_insert_with(|| changes.add_floats(&split.vertex_tangents, false));
    let keeps = c.keeps_vertices(topology);
    let mut edit = PrimitiveEdit {
        remove_draco: primitive
            .get("extensions")
            .and_then(|e| e.get("KHR_draco_mesh_compression"))
            .is_some(),
        ..PrimitiveEdit::default()
    };
    let index_of = |n: &Node| n.as_u64().and_then(|i| usize::try_from(i).ok());
    let mut remap =
        |index: usize, is_position: bool, changes: &mut Changes| -> Result<Ref, SceneError> {
            if let Some(r) = remapped.get(&(job, index)) {
                return Ok(*r);
            }
            let r = changes.add_remapped(
                root,
                buffers,
                index,
                &split.source_vertex,
                max_vertices,
                is_position,
            )?;
            remapped.insert((job, index), r);
            Ok(r)
        };
    for member in primitive
        .get("attributes")
        .and_then(Node::as_object)
        .unwrap_or(&[])
    {
        if member.key == "TANGENT" || keeps {
            continue;
        }
        if let Some(index) = index_of(&member.value) {
            let r = remap(index, member.key == "POSITION", changes)?;
            edit.attributes.push((member.key.clone(), r));
        }
    }
    edit.attributes.push(("TANGENT".into(), tangent));
    if let Some(normals) = &c.tangents.normals {
        let r = *refs
            .normal
            .get_or_insert_with(|| changes.add_floats(normals, false));
        edit.attributes.push(("NORMAL".into(), r));
    }
    if !keeps {
        let r = *refs
            .indices
            .get_or_insert_with(|| changes.add_indices(&split.indices, split.source_vertex.len()));
        edit.indices = Some(r);
        edit.to_triangle_list = topology != Topology::Triangles;
    }
    let targets = primitive
        .get("targets")
        .and_then(Node::as_array)
        .unwrap_or(&[]);
    for (t, target) in targets.iter().enumerate() {
        let delta = c.target_deltas.get(t).and_then(Option::as_ref);
        let mut set = Vec::new();
        if !keeps {
            for member in target.as_object().unwrap_or(&[]) {
                if member.key == "TANGENT" && delta.is_some() {
                    continue;
                }
                if let Some(index) = index_of(&member.value) {
                    let r = remap(index, member.key == "POSITION", changes)?;
                    set.push((member.key.clone(), r));
                }
            }
        }
        if let Some(deltas) = delta {
            let r = *refs
                .deltas
                .entry(t)
                .or_insert_with(|| changes.add_floats(deltas, false));
            set.push(("TANGENT".into(), r));
        }
        edit.targets.push(set);
    }
    Ok(edit)
}
