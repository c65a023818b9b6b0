//! glTF 2.0: the GLB container, the accessor decoder, the lossless JSON reader and splice
//! editor, and [`process`], which puts them together: load, decide, compute once per distinct
//! geometry, write back only what changed, and report.

pub mod accessor;
pub mod compute;
pub(crate) mod created;
pub mod debug;
pub mod draco;
pub mod glb;

pub mod load;

pub mod plan;
pub mod quantize;
pub mod refs;
pub mod sizes;
pub mod write;

use crate::scene::error::{ProblemCode, SceneError};
use crate::scene::layout::{Layout, PrimitiveRef};
use crate::scene::options::{Debug, Timings};
use crate::scene::pieces::Pieces;
use crate::scene::report::{
    DebugClassReport, DebugColorsReport, MorphReport, Notice, PrimitiveAction, PrimitiveReport,
    Report, StorageChange, StorageReport, TangentReport, thousands,
};
use crate::scene::{OutputFormat, Processed, SceneOptions, TangentType};
use accessor::{Data, DecodedAccessors};
use compute::{Computed, GeometryLimits};
use debug::Painted;
use load::{LoadLimits, Resources};
use plan::{Action, GeometryKey, PlanOptions, PrimitivePlan, Topology};
use quantize::Snorm;
use rayon::prelude::*;
use std::collections::HashMap;
use std::collections::hash_map::Entry;
use tspace_json::{Node, Text};
use tspace_tangent::{Cancel, Marks, Method, Options, UvOrigin};
use write::{Changes, PendingFloats, PrimitiveEdit, Ref};

fn accessor_count(root: &Node, index: Option<usize>) -> usize {
    index
        .and_then(|i| root.get("accessors")?.index(i)?.get("count")?.as_u64())
        .and_then(|n| usize::try_from(n).ok())
        .unwrap_or(0)
}

fn primitive_node(root: &Node, (mesh, primitive): (usize, usize)) -> Option<&Node> {
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

/// [`process`], with the choices of [`Internal`]: load, plan the jobs, compute them, report
/// every primitive (collecting the edits as it goes), write; then measure what was written.
pub fn process_with<'a>(
    bytes: &'a [u8],
    resources: &dyn Resources<'a>,
    options: &SceneOptions,
    internal: &Internal,
) -> Result<Processed, SceneError> {
    let (mut processed, sizes_in) = process_and_write(bytes, resources, options, internal)?;
    // The input's tree, the computations and the edits are gone by now. The output is measured
    // from its text, without a tree (`sizes::measure_text`).
    let json = match (&processed.bytes, &processed.pieces) {
        (Some(written), _) => Some(output_json(written, options.format)?),
        (None, Some(pieces)) => Some(match pieces.json() {
            Some(json) => json,
            // The input passed through whole: its JSON is the output's.
            None => output_json(bytes, OutputFormat::Glb)?,
        }),
        (None, None) => None,
    };
    report_storage(&mut processed.report, sizes_in, json)?;
    processed.report.finish();
    processed.timings.lap("storage report");
    Ok(processed)
}

/// Everything but measuring the output: the scene processed and written, with the input's
/// mesh sizes. What it builds on the way, the input's tree first, is dropped when it returns.
fn process_and_write<'a>(
    bytes: &'a [u8],
    resources: &dyn Resources<'a>,
    options: &SceneOptions,
    internal: &Internal,
) -> Result<(Processed, sizes::MeshSizes), SceneError> {
    let limits = options.limits;
    let load_limits = LoadLimits {
        max_buffer_bytes: limits.max_buffer_bytes,
    };
    // Between steps, work nobody waits for any more stops (see SceneOptions::cancel).
    let cancel = &options.cancel;
    let mut timings = Timings::start();
    let loaded = load::load(bytes, resources, &load_limits)?;
    timings.lap("load");
    SceneError::check(cancel)?;
    let root = loaded.doc.root();
    let (plans, jobs) = plan_jobs(root, &plan_options(options, internal), options.method);
    check_triangle_budget(root, &jobs, limits.max_triangles)?;
    let buffers = loaded.buffer_slices();
    timings.lap("plan");
    let decoded = decode_draco(root, &plans, &jobs, &buffers, options)?;
    timings.lap("decode draco");
    SceneError::check(cancel)?;
    let data = Data {
        buffers: &buffers,
        decoded: &decoded,
    };
    let mut computed = compute_jobs(root, &jobs, data, options)?;
    timings.lap("compute");
    SceneError::check(cancel)?;
    let painting = options.write && options.debug == Debug::Colors;
    let marks = if options.layouts || painting {
        mark_jobs(&jobs, &computed, options)
    } else {
        Vec::new()
    };
    let painted: Vec<Painted> = if painting {
        computed
            .par_iter_mut()
            .zip(&marks)
            .map(|(c, marks)| debug::paint(c, marks))
            .collect()
    } else {
        Vec::new()
    };
    let layouts = if options.layouts {
        layouts(&plans, &computed, marks)
    } else {
        Vec::new()
    };
    timings.lap("marks");
    let scene = Scene {
        cancel,
        root,
        data,
        max_vertices: limits.max_vertices,
        tangents: options.tangents,
        compressed_output: write::compress::resolve(options.compress, root)
            == write::compress::Output::Meshopt,
        painted: &painted,
    };
    let mut report = report_header(bytes, &loaded, options);
    let mut edits = report_primitives(&scene, &plans, &jobs, computed, &mut report)?;
    if painting {
        report_painting(&mut report, root, &painted, &mut edits);
    }
    timings.lap("report and edits");
    SceneError::check(cancel)?;
    // The writer reads the input and the edits alone: what the computations left goes before
    // it allocates the output (in a scene of many small primitives, as much as the output).
    let Edits {
        changes,
        job_refs,
        remapped,
    } = edits;
    // What borrows the decoded accessors (see compute::Geometry) goes first.
    drop((plans, jobs, painted, job_refs, remapped));
    drop(decoded);
    let sizes_in = sizes::measure(root);
    let output = write_scene(bytes, loaded, changes, options, resources, &mut report)?;
    timings.lap("write");
    let (bytes, pieces) = match output {
        Some(Output::Bytes(bytes)) => (Some(bytes), None),
        Some(Output::Pieces(pieces)) => (None, Some(pieces)),
        None => (None, None),
    };
    let processed = Processed {
        bytes,
        pieces,
        report,
        layouts,
        timings,
    };
    Ok((processed, sizes_in))
}

/// Every job's marks: each triangle's findings and each flip vertex, by the same test the core's
/// diagnostics count with, under the same options.
fn mark_jobs(jobs: &[Job], computed: &[Computed], options: &SceneOptions) -> Vec<Marks> {
    jobs.par_iter()
        .zip(computed)
        .map(|(job, computed)| {
            let core_options = Options {
                method: job.method,
                uv_origin: UvOrigin::TopLeft,
                normal_mode: options.normal_mode,
                ..Options::default()
            };
            tspace_tangent::marks(
                &computed.geometry.input(),
                &core_options,
                &computed.tangents,
            )
        })
        .collect()
}

/// The texture layout of every job that has texture coordinates (not the axis method's), with
/// its marks.
fn layouts(plans: &[PrimitivePlan], computed: &[Computed], marks: Vec<Marks>) -> Vec<Layout> {
    let mut layouts: Vec<Option<Layout>> = computed
        .par_iter()
        .zip(marks)
        .map(|(computed, marks)| {
            let geometry = &computed.geometry;
            let uvs = geometry.uvs.as_deref()?.to_vec();
            Some(Layout {
                primitives: Vec::new(),
                texcoord: 0,
                uvs,
                indices: geometry.indices.as_deref().map(<[u32]>::to_vec),
                marks,
                repaired_corners: computed
                    .tangents
                    .diagnostics
                    .fallback_tangents
                    .corners
                    .count,
            })
        })
        .collect();
    for plan in plans {
        let Some(Some(layout)) = plan.job().and_then(|j| layouts.get_mut(j)) else {
            continue;
        };
        if layout.primitives.is_empty() {
            layout.texcoord = plan.texcoord_set;
        }
        let (mesh, primitive) = plan.at();
        layout.primitives.push(PrimitiveRef {
            mesh,
            primitive,
            mesh_name: plan.mesh_name.as_deref().map(str::to_owned),
        });
    }
    layouts.into_iter().flatten().collect()
}

fn plan_options(options: &SceneOptions, internal: &Internal) -> PlanOptions {
    PlanOptions {
        overwrite: options.overwrite,
        all: options.all,
        axis: options.method == Method::Axis,
        no_material_means_tangents: internal.no_material_means_tangents,
    }
}

/// One computation: a distinct geometry under one method. Primitives that share accessors
/// (instanced copies, one mesh under several materials) share its job, so each geometry is
/// computed, and its new accessors written, once.
struct Job {
    key: GeometryKey,
    method: Method,
    /// The first primitive that needed it, `[mesh, primitive]`, for messages.
    first: [u32; 2],
}

impl Job {
    /// Where the job's first primitive is, as messages name it. Made when needed rather than
    /// kept: a scene may have a job per primitive.
    fn path(&self) -> String {
        let [mesh, primitive] = self.first;
        format!("meshes[{mesh}].primitives[{primitive}]")
    }
}

/// Plans every primitive and numbers the computations they need: primitives with the same
/// geometry under the same method share one job, in the order primitives first need them.
fn plan_jobs(root: &Node, options: &PlanOptions, method: Method) -> (Vec<PrimitivePlan>, Vec<Job>) {
    let mut jobs: Vec<Job> = Vec::new();
    let mut index: HashMap<(GeometryKey, Method), usize> = HashMap::new();
    let plans = plan::plan(root, options, |plan, key| {
        // Audits always compare with MikkTSpace, what the existing tangents' bakers used.
        let method = match plan.action {
            Action::Audit => Method::MikkTSpace,
            _ => method,
        };
        let next = jobs.len();
        match index.entry((key, method)) {
            Entry::Occupied(job) => *job.get(),
            Entry::Vacant(slot) => {
                let key = slot.key().0.clone();
                slot.insert(next);
                let first = [plan.mesh, plan.primitive];
                jobs.push(Job { key, method, first });
                next
            }
        }
    });
    // Kept to the end, beside one plan per primitive: no room to spare.
    jobs.shrink_to_fit();
    (plans, jobs)
}

/// Decodes the Draco stream of every primitive a job reads whose accessors have no data of their
/// own, once per stream and geometry, in parallel. Runs after the triangle budget, so no stream
/// is decoded for a scene that would be refused anyway.
fn decode_draco(
    root: &Node,
    plans: &[PrimitivePlan],
    jobs: &[Job],
    buffers: &[&[u8]],
    options: &SceneOptions,
) -> Result<DecodedAccessors, SceneError> {
    let mut seen = std::collections::HashSet::new();
    let wanted: Vec<(&Node, String)> = plans
        .iter()
        .filter_map(|plan| {
            let key = &jobs.get(plan.job()?)?.key;
            let primitive = primitive_node(root, plan.at())?;
            let stream = draco::extension(primitive)?
                .get("bufferView")
                .and_then(Node::as_u64);
            let key = (stream, key);
            (draco::needs_decoding(root, primitive) && seen.insert(key)).then(|| {
                let path = format!("meshes[{}].primitives[{}]", plan.mesh, plan.primitive);
                (primitive, path)
            })
        })
        .collect();
    let limits = draco::DracoLimits {
        max_vertices: options.limits.max_vertices,
        max_triangles: options.limits.max_triangles,
        max_bytes: options.limits.max_buffer_bytes,
    };
    let results: Vec<_> = wanted
        .par_iter()
        .map(|(primitive, path)| draco::decode_primitive(root, primitive, path, buffers, &limits))
        .collect();
    let mut decoded = DecodedAccessors::new();
    for result in results {
        decoded.extend(result?);
    }
    Ok(decoded)
}

/// Whether any accessor of the primitive (attributes or indices) was decoded: its accessors
/// then hold no data in the file, so every one must be written out.
fn reads_decoded(primitive: &Node, decoded: &DecodedAccessors) -> bool {
    let index = |n: &Node| n.as_u64().and_then(|i| usize::try_from(i).ok());
    let attributes = primitive
        .get("attributes")
        .and_then(Node::as_object)
        .unwrap_or(&[]);
    attributes
        .iter()
        .filter_map(|m| index(&m.value))
        .chain(primitive.get("indices").and_then(index))
        .any(|a| decoded.contains_key(&a))
}

/// Refuses the scene before anything is decoded when its jobs, morph targets included (each is
/// computed like the base mesh), add up to more triangles than the limit.
fn check_triangle_budget(
    root: &Node,
    jobs: &[Job],
    max_triangles: usize,
) -> Result<(), SceneError> {
    let mut planned = 0usize;
    for Job { key, .. } in jobs {
        let corners = match key.indices {
            Some(_) => accessor_count(root, key.indices),
            None => accessor_count(root, Some(key.position)),
        };
        let per_target = 1 + key.targets.len();
        planned = planned.saturating_add(corners / 3 * per_target);
    }
    if planned > max_triangles {
        return Err(SceneError::new(
            ProblemCode::TooManyTriangles,
            format!(
                "the scene needs tangents for {planned} triangles (morph targets included); the limit is {max_triangles}"
            ),
        ));
    }
    Ok(())
}

/// Runs every job, in parallel. All run to the end, so that the error returned is the first in
/// job order, whatever the threads' timing.
fn compute_jobs<'a>(
    root: &Node,
    jobs: &[Job],
    data: Data<'a>,
    options: &SceneOptions,
) -> Result<Vec<Computed<'a>>, SceneError> {
    let limits = GeometryLimits {
        max_vertices: options.limits.max_vertices,
        max_triangles: options.limits.max_triangles,
    };
    let results: Vec<Result<Computed, SceneError>> = jobs
        .par_iter()
        .map(|job| {
            SceneError::check(&options.cancel)?;
            // Large meshes are worth spreading over the threads inside the core too.
            let large = accessor_count(root, job.key.indices.or(Some(job.key.position))) > 300_000;
            let core_options = Options {
                method: job.method,
                uv_origin: UvOrigin::TopLeft,
                normal_mode: options.normal_mode,
                parallel: large,
                ..Options::default()
            };
            let run = compute::Run {
                options: &core_options,
                limits: &limits,
                cancel: &options.cancel,
            };
            compute::compute(root, &job.key, data, &run, &job.path())
        })
        .collect();
    results.into_iter().collect()
}

/// The report's header: what came in and what was asked. Input bytes count the external
/// buffers read; the writer adds the external images it embeds.
fn report_header(bytes: &[u8], loaded: &load::Loaded<'_>, options: &SceneOptions) -> Report {
    let external_buffer_bytes = loaded
        .buffers
        .iter()
        .filter(|b| matches!(b.source, load::BufferSource::External(_)))
        .map(|b| b.bytes.len() as u64)
        .sum::<u64>();
    Report {
        report_version: crate::scene::report::REPORT_VERSION,
        tspace_version: env!("CARGO_PKG_VERSION"),
        input_format: match loaded.container {
            load::Container::Glb => "glb",
            load::Container::Json => "gltf",
        },
        input_bytes: bytes.len() as u64 + external_buffer_bytes,
        method: options.method.name(),
        overwrite: options.overwrite,
        all: options.all,
        ..Report::default()
    }
}

/// What every primitive's step reads.
struct Scene<'s> {
    cancel: &'s Cancel,
    root: &'s Node,
    data: Data<'s>,
    max_vertices: usize,
    tangents: TangentType,
    /// The views tspace writes are meshopt-compressed.
    compressed_output: bool,
    /// With debug colours: every job's colours (indexed by job); else empty.
    painted: &'s [Painted],
}

/// One report entry per plan, in plan order, and the report's totals; for each primitive that
/// gets tangents, its edit. A computation's results are freed once its last primitive is
/// reported (they are in the edits by then), so that the report's entries reuse their space.
fn report_primitives(
    scene: &Scene<'_>,
    plans: &[PrimitivePlan],
    jobs: &[Job],
    computed: Vec<Computed>,
    report: &mut Report,
) -> Result<Edits, SceneError> {
    let mut edits = Edits::default();
    report.summary.computations = computed.len() as u64;
    // Per job, the first and the last plan that use it: the first's entry carries the job's
    // findings (the others name it in `shared_with`), and after the last its computation goes.
    let mut plans_of_job: Vec<Option<(usize, usize)>> = vec![None; computed.len()];
    for (p, plan) in plans.iter().enumerate() {
        if let Some(span) = plan.job().and_then(|j| plans_of_job.get_mut(j)) {
            span.get_or_insert((p, p)).1 = p;
        }
    }
    // Each job adds its accessors once: room for them all, rather than lists grown by doubling
    // (capacity no job uses is never touched). A job writes its tangents, and its generated
    // normals and debug colours when it has them; only remapped attributes are left to grow
    // the lists.
    edits.job_refs.reserve_exact(jobs.len());
    let added: usize = computed
        .iter()
        .enumerate()
        .map(|(j, c)| {
            1 + usize::from(c.tangents.normals.is_some())
                + usize::from(scene.painted.get(j).is_some())
        })
        .sum();
    edits.changes.reserve(added, plans.len());
    report.primitives.reserve_exact(plans.len());
    let mut computed: Vec<Option<Computed>> = computed.into_iter().map(Some).collect();
    for (p, plan) in plans.iter().enumerate() {
        SceneError::check(scene.cancel)?;
        let job = plan.job();
        let span = job.and_then(|j| plans_of_job.get(j).copied().flatten());
        let shared_with = span
            .map(|(first, _)| first)
            .filter(|&first| first != p)
            .and_then(|first| plans.get(first))
            .map(|first| [first.mesh, first.primitive]);
        report_primitive(
            scene,
            (plan, jobs, shared_with),
            &computed,
            &mut edits,
            report,
        )?;
        if let Some(j) = job.filter(|_| span.is_some_and(|(_, last)| last == p))
            && let Some(mut c) = computed.get_mut(j).and_then(Option::take)
        {
            let refs = edits.job_refs.get_mut(j);
            let written = refs.as_ref().is_some_and(|refs| refs.written);
            if let Some(pending) = refs.and_then(|refs| refs.pending_tangents.take()) {
                let tangents = std::mem::take(&mut c.tangents.split.vertex_tangents);
                edits.changes.fill_floats(pending, tangents)?;
            }
            add_totals(&mut report.summary, &c, written);
        }
    }
    Ok(edits)
}

/// One plan's report entry (naming the first primitive with the same geometry when that is
/// another), and its edit when it gets tangents.
fn report_primitive(
    scene: &Scene<'_>,
    (plan, jobs, shared_with): (&PrimitivePlan, &[Job], Option<[u32; 2]>),
    computed: &[Option<Computed>],
    edits: &mut Edits,
    report: &mut Report,
) -> Result<(), SceneError> {
    report.summary.primitives += 1;
    let mut entry = report_entry(plan, shared_with);
    let computation = plan
        .job()
        .and_then(|j| Some((j, &jobs.get(j)?.key, computed.get(j)?.as_ref()?)));
    match (&plan.action, computation) {
        (Action::Skip(reason), _) => {
            report.summary.skipped += 1;
            entry.action = PrimitiveAction::Skipped;
            entry.reason = Some(reason.code());
            entry.message = Some(reason.message().into_boxed_str());
        }
        (Action::Audit, Some((j, key, c))) => {
            report.summary.audited += 1;
            audit_primitive(scene, plan, c, &mut entry, report)?;
            if let Some(primitive) = primitive_node(scene.root, plan.at())
                && let Some(edit) = edits.paint_kept(scene, primitive, key.topology, j, c)?
            {
                edits.changes.primitives.insert(plan.at(), edit);
            }
        }
        (Action::Generate, Some((j, key, c))) => {
            report.summary.generated += 1;
            if !generate_primitive(scene, plan, (j, key), c, &mut entry, edits)? {
                return Ok(());
            }
        }
        _ => entry.action = PrimitiveAction::Skipped,
    }
    if let Some(note) = painted_note(scene.root, plan, edits) {
        entry.notes.push(note);
    }
    report.primitives.push(entry);
    Ok(())
}

/// A painted primitive's note: what it lost in the debug output.
fn painted_note(root: &Node, plan: &PrimitivePlan, edits: &Edits) -> Option<String> {
    edits.changes.primitives.get(&plan.at())?.material?;
    let primitive = primitive_node(root, plan.at())?;
    let material = match plan.material {
        Some(m) => format!("material {m}"),
        None => "no material".to_owned(),
    };
    let color = match primitive.get("attributes").and_then(|a| a.get("COLOR_0")) {
        Some(_) => " and its own COLOR_0",
        None => "",
    };
    Some(format!(
        "debug colours: painted by finding; {material}{color} replaced in this output"
    ))
}

/// The report's account of the debug colours, and the material they need when any primitive
/// was painted.
fn report_painting(report: &mut Report, root: &Node, painted: &[Painted], edits: &mut Edits) {
    let primitives = edits
        .changes
        .primitives
        .values()
        .filter(|e| e.material.is_some())
        .count() as u64;
    let mut triangles = [0u64; 5];
    let mut vertices_added = 0;
    for p in painted {
        for (total, count) in triangles.iter_mut().zip(p.triangles) {
            *total += count;
        }
        vertices_added += p.vertices_added;
    }
    let material = (primitives > 0).then(|| {
        edits
            .changes
            .materials
            .push(debug::MATERIAL_JSON.to_owned());
        edits.changes.extensions_used.push(debug::UNLIT);
        root.get("materials")
            .and_then(Node::as_array)
            .map_or(0, <[Node]>::len)
    });
    let classes: Vec<DebugClassReport> = debug::Class::ALL
        .iter()
        .map(|&class| DebugClassReport {
            class: class.name(),
            color: class.hex(),
            triangles: triangles[class as usize],
        })
        .collect();
    let counted = classes
        .iter()
        .filter(|c| c.triangles > 0 && c.class != debug::Class::Ordinary.name())
        .map(|c| format!("{} {} ({})", thousands(c.triangles), c.class, c.color))
        .collect::<Vec<_>>();
    let found = if counted.is_empty() {
        "every triangle ordinary".to_owned()
    } else {
        counted.join(", ")
    };
    report.notices.push(if primitives == 0 {
        Notice::new(
            "debug_colors_unused",
            "debug colours: no primitive was painted, as none gets tangents or an audit; the scene is written as it would be without the option",
        )
    } else {
        Notice::new(
            "debug_colors",
            format!(
                "debug colours: {primitives} primitive(s) painted by what tspace found in each triangle ({found}; ordinary #c9c9c9), with {vertices_added} vertices added where classes meet and an unlit material replacing theirs: this scene is for looking, not for shipping"
            ),
        )
    });
    report.debug_colors = Some(DebugColorsReport {
        primitives,
        material,
        vertices_added,
        classes,
    });
}

/// What the plan knows of a primitive, before any action.
fn report_entry(plan: &PrimitivePlan, shared_with: Option<[u32; 2]>) -> PrimitiveReport {
    PrimitiveReport {
        mesh: plan.mesh,
        primitive: plan.primitive,
        mesh_name: plan.mesh_name.clone(),
        material: plan.material.map(|m| m as u64),
        uses: plan.uses,
        texcoord: plan.texcoord_set,
        notes: plan.notes.clone(),
        shared_with,
        ..PrimitiveReport::default()
    }
}

/// Primitives that share a computation share its diagnostics: the report gives them once, on
/// the first, or a scene of many copies would grow huge.
fn add_diagnostics(entry: &mut PrimitiveReport, c: &Computed) {
    if entry.shared_with.is_none() {
        entry.diagnostics = Some(Box::new((&c.tangents.diagnostics).into()));
    }
}

/// Compares the primitive's own tangents with MikkTSpace's; the file is left as it is.
fn audit_primitive(
    scene: &Scene<'_>,
    plan: &PrimitivePlan,
    c: &Computed,
    entry: &mut PrimitiveReport,
    report: &mut Report,
) -> Result<(), SceneError> {
    entry.action = PrimitiveAction::Audited;
    let tangent = primitive_node(scene.root, plan.at())
        .and_then(|n| n.get("attributes")?.get("TANGENT")?.as_u64())
        .and_then(|i| usize::try_from(i).ok());
    if let Some(index) = tangent {
        let described = scene
            .data
            .accessor(scene.root, index)
            .map_err(compute::accessor_error)?;
        let existing = accessor::read_floats::<4>(&described, scene.max_vertices)
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
    add_diagnostics(entry, c);
    Ok(())
}

/// Gives the primitive its job's tangents: reports it and records its edit. Returns false,
/// and the entry is left out of the report, when the primitive is not found again (plans come
/// from this very document, so it always is).
fn generate_primitive(
    scene: &Scene<'_>,
    plan: &PrimitivePlan,
    (job, key): (usize, &GeometryKey),
    c: &Computed,
    entry: &mut PrimitiveReport,
    edits: &mut Edits,
) -> Result<bool, SceneError> {
    entry.action = if plan.had_tangents {
        PrimitiveAction::Overwritten
    } else {
        PrimitiveAction::Generated
    };
    add_diagnostics(entry, c);
    let Some(primitive) = primitive_node(scene.root, plan.at()) else {
        return Ok(false);
    };
    let snorm = tangent_snorm(scene, key, c).map(|snorm| TangentStorage {
        snorm,
        octahedral: scene.compressed_output && octahedral_normals(scene, key),
    });
    let edit = edits.edit_primitive(scene, primitive, key.topology, job, c, snorm)?;
    entry.tangent = edits
        .job_refs
        .get(job)
        .and_then(|refs| refs.tangent)
        .map(|(_, quantized)| TangentReport::new(quantized));
    if !key.targets.is_empty() {
        entry.morph_targets = Some(Box::new(MorphReport {
            targets: key.targets.len() as u64,
            with_tangent_deltas: c.target_deltas.iter().filter(|d| d.is_some()).count() as u64,
            handedness_changes: c.morph_handedness_changes,
        }));
    }
    edits.changes.primitives.insert(plan.at(), edit);
    Ok(true)
}

/// Adds one computation to the summary's totals. Only jobs whose accessors were written added
/// vertices (an audit adds none).
fn add_totals(summary: &mut crate::scene::report::Summary, c: &Computed, written: bool) {
    let d = &c.tangents.diagnostics;
    summary.triangles += d.triangles;
    summary.fallback_tangents += d.fallback_tangents.corners.count;
    summary.handedness_flip_vertices += d.handedness_flip_vertices.count;
    summary.degenerate_triangles +=
        d.duplicate_position_triangles.count + d.zero_area_triangles.count;
    summary.zero_uv_area_triangles += d.zero_uv_area_triangles.count;
    summary.mirrored_uv_triangles += d.mirrored_uv_triangles.count;
    if written {
        summary.vertices_added += d.vertices_added;
    }
}

/// The written scene: one vector, or with [`SceneOptions::in_pieces`] the pieces it is made of.
enum Output {
    Bytes(Vec<u8>),
    Pieces(Pieces),
}

impl Output {
    fn len(&self) -> usize {
        match self {
            Output::Bytes(bytes) => bytes.len(),
            Output::Pieces(pieces) => pieces.len(),
        }
    }
}

/// The output, unless only analysing; what the writer found goes into the report.
fn write_scene<'a>(
    bytes: &[u8],
    loaded: load::Loaded<'a>,
    changes: Changes,
    options: &SceneOptions,
    resources: &dyn Resources<'a>,
    report: &mut Report,
) -> Result<Option<Output>, SceneError> {
    if !options.write {
        report
            .notices
            .extend(write::unsupplied_images(loaded.doc.root(), resources));
        return Ok(None);
    }
    let in_pieces = options.in_pieces && options.format == OutputFormat::Glb;
    let keeps_layout = write::compress::resolve(options.compress, loaded.doc.root())
        == write::compress::Output::Keep;
    let out = if changes.primitives.is_empty()
        && keeps_layout
        && loaded.container == load::Container::Glb
        && options.format == OutputFormat::Glb
    {
        // Nothing to change: the input is the output, byte for byte.
        match in_pieces {
            true => Output::Pieces(Pieces::whole_input(bytes.len())),
            false => Output::Bytes(bytes.to_vec()),
        }
    } else {
        let pieces_of = in_pieces.then_some(bytes);
        let written = write::write(
            loaded,
            changes,
            options.format,
            options.compress,
            resources,
            pieces_of,
            options.release_freed_memory,
        )?;
        report.input_bytes += written.embedded_image_bytes;
        report.dropped = written.dropped;
        report.notices.extend(written.notices);
        match written.pieces {
            Some(pieces) => Output::Pieces(pieces),
            None => Output::Bytes(written.bytes),
        }
    };
    report.output_format = Some(options.format.name());
    report.output_bytes = Some(out.len() as u64);
    Ok(Some(out))
}

/// The normalized type TANGENT takes: NORMAL's own when it is a normalized BYTE or SHORT read
/// from the file (generated normals are float), unless float is asked for.
fn tangent_snorm(scene: &Scene<'_>, key: &GeometryKey, c: &Computed) -> Option<Snorm> {
    if scene.tangents == TangentType::Float || c.tangents.normals.is_some() {
        return None;
    }
    // The two members alone: the whole accessor's description (its view looked up and
    // checked) was a twentieth of a JSON-heavy scene's run, once per primitive. The normals
    // were read through that description already, so it is valid.
    let normal = scene.root.get("accessors")?.index(key.normal?)?;
    let component_type = normal.get("componentType")?.as_u64()?;
    let normalized = normal.get("normalized").and_then(Node::as_bool) == Some(true);
    match (
        accessor::ComponentType::from_code(component_type)?,
        normalized,
    ) {
        (accessor::ComponentType::I8, true) => Some(Snorm::I8),
        (accessor::ComponentType::I16, true) => Some(Snorm::I16),
        _ => None,
    }
}

/// How a quantized TANGENT is stored: its type, and whether in the OCTAHEDRAL filter's values.
#[derive(Clone, Copy)]
struct TangentStorage {
    snorm: Snorm,
    /// Compressed output of a primitive whose NORMAL the input stored with meshopt's OCTAHEDRAL
    /// filter: the tangents take that representation too (see `quantize::octahedral_tangents`).
    octahedral: bool,
}

/// Whether the key's NORMAL is stored in a meshopt view with the OCTAHEDRAL filter.
fn octahedral_normals(scene: &Scene<'_>, key: &GeometryKey) -> bool {
    let view = key
        .normal
        .and_then(|n| {
            scene
                .root
                .get("accessors")?
                .index(n)?
                .get("bufferView")?
                .as_u64()
        })
        .and_then(|v| {
            scene
                .root
                .get("bufferViews")?
                .index(usize::try_from(v).ok()?)
        });
    let extensions = view.and_then(|v| v.get("extensions"));
    ["EXT_meshopt_compression", "KHR_meshopt_compression"]
        .iter()
        .any(|name| {
            extensions
                .and_then(|e| e.get(name)?.get("filter")?.as_str())
                .is_some_and(|f| f == "OCTAHEDRAL")
        })
}

/// The job's TANGENT accessor: float, or quantized to `storage`'s type as close to the float
/// tangents as the type (or the octahedral filter) allows, and as orthogonal to the decoded
/// normals, with the largest angle that added. Float tangents are the computation's own,
/// moved into the output once its last primitive is reported: the view waits for them.
fn add_tangents(
    changes: &mut Changes,
    c: &Computed,
    storage: Option<TangentStorage>,
) -> (AddedTangents, Option<PendingFloats>) {
    let split = &c.tangents.split;
    let Some(TangentStorage { snorm, octahedral }) = storage else {
        let (r, pending) = changes.add_floats_later(split.vertex_tangents.len());
        return ((r, None), Some(pending));
    };
    let source_normals = c.geometry.normals.as_deref().unwrap_or(&[]);
    let normals: Vec<[f32; 3]> = split
        .source_vertex
        .iter()
        .filter_map(|&v| source_normals.get(v as usize).copied())
        .collect();
    let count = split.vertex_tangents.len();
    let vec4 = accessor::ElementType::Vec4;
    if octahedral {
        let (quantized, stored) =
            quantize::octahedral_tangents(&split.vertex_tangents, &normals, snorm);
        let prefiltered = write::compress::Prefiltered {
            bytes: stored,
            filter: tspace_meshopt::Filter::Octahedral,
        };
        let degrees = quantized.max_added_degrees;
        let r = changes.add_snorm_filtered(quantized.bytes, count, snorm, vec4, Some(prefiltered));
        return ((r, Some((snorm, degrees))), None);
    }
    let quantized = quantize::quantize_tangents(&split.vertex_tangents, &normals, snorm);
    let r = changes.add_snorm(quantized.bytes, count, snorm, vec4);
    ((r, Some((snorm, quantized.max_added_degrees))), None)
}

/// A morph target's TANGENT deltas: in the base TANGENT's normalized type when every component
/// fits in [-1, 1] (KHR_mesh_quantization allows it), else float.
fn add_deltas(changes: &mut Changes, deltas: &[[f32; 3]], snorm: Option<Snorm>) -> Ref {
    match snorm.and_then(|s| Some((s, quantize::quantize_deltas(deltas, s)?))) {
        Some((snorm, bytes)) => {
            changes.add_snorm(bytes, deltas.len(), snorm, accessor::ElementType::Vec3)
        }
        None => changes.add_floats(deltas, false),
    }
}

/// Each primitive's storage in and out, and the scene's mesh bytes, from the input's sizes and
/// (when written) the output's document, which is read again: the sizes are what the files
/// declare.
fn report_storage(
    report: &mut Report,
    before: sizes::MeshSizes,
    output_json: Option<&[u8]>,
) -> Result<(), SceneError> {
    let after = output_json.map(output_sizes).transpose()?;
    report.summary.mesh_bytes_in = before.total;
    report.summary.mesh_bytes_out = after.as_ref().map(|a| a.total);
    for entry in &mut report.primitives {
        let key = (entry.mesh as usize, entry.primitive as usize);
        let Some(input) = before.primitive(key) else {
            continue;
        };
        let output = after.as_ref().and_then(|a| a.primitive(key));
        entry.storage = Some(Box::new(StorageReport {
            compression_in: input.compression,
            compression_out: output.map(|o| o.compression),
            bytes_in: input.bytes,
            bytes_out: output.map(|o| o.bytes),
            why: output.and_then(|o| why_storage_changed(input.compression, o.compression)),
        }));
    }
    Ok(())
}

/// The JSON of a written file.
fn output_json(bytes: &[u8], format: OutputFormat) -> Result<&[u8], SceneError> {
    match format {
        OutputFormat::Glb => glb::parse(bytes).map(|g| g.json).map_err(|e| {
            SceneError::new(
                ProblemCode::Internal,
                format!("tspace's own output does not parse again: {e}"),
            )
        }),
        OutputFormat::GltfEmbedded => Ok(bytes),
    }
}

fn output_sizes(json: &[u8]) -> Result<sizes::MeshSizes, SceneError> {
    sizes::measure_text(json).ok_or_else(|| {
        SceneError::new(
            ProblemCode::Internal,
            "tspace's own output does not read again as a glTF document",
        )
    })
}

fn why_storage_changed(
    input: sizes::Compression,
    output: sizes::Compression,
) -> Option<StorageChange> {
    use sizes::Compression::{Draco, Meshopt, None};
    match (input, output) {
        (Draco, None) => Some(StorageChange::OutOfDraco),
        (Draco, Meshopt) => Some(StorageChange::DracoToMeshopt),
        (Meshopt, None) => Some(StorageChange::Uncompressed),
        (None, Meshopt) => Some(StorageChange::ToMeshopt),
        _ => Option::None,
    }
}

/// A job's TANGENT accessor, and for a quantized one its type and the largest angle it added.
type AddedTangents = (Ref, Option<(Snorm, f32)>);

/// The accessors one job adds, shared by every primitive that uses it.
#[derive(Default)]
struct JobRefs {
    tangent: Option<AddedTangents>,
    /// A float TANGENT accessor's view, until the job's tangents are moved into it.
    pending_tangents: Option<PendingFloats>,
    /// With debug colours, COLOR_0.
    color: Option<Ref>,
    normal: Option<Ref>,
    indices: Option<Ref>,
    /// Per morph target that has them: its TANGENT deltas.
    deltas: Vec<(usize, Ref)>,
    /// Whether the job's accessors were written (an audit's are not).
    written: bool,
}

/// Job `job`'s accessors, now counted as written. The list is reserved for every job up front
/// and grows to `job` here, so that it never doubles.
fn written_refs(list: &mut Vec<JobRefs>, job: usize) -> &mut JobRefs {
    if list.len() <= job {
        list.resize_with(job + 1, JobRefs::default);
    }
    let refs = &mut list[job];
    refs.written = true;
    refs
}

/// What the primitives' edits add to the scene, for the writer.
#[derive(Default)]
struct Edits {
    changes: Changes,
    /// Per job (up to the last that was written): its accessors.
    job_refs: Vec<JobRefs>,
    /// Per (job, input accessor): that accessor copied in the order of the job's split
    /// vertices, so primitives sharing a job also share the copies.
    remapped: HashMap<(usize, usize), Ref>,
}

impl Edits {
    /// The edit that gives `primitive` its job's tangents. When the job split vertices (or
    /// generated normals, or unrolled a strip), every other attribute, the indices and each
    /// morph target's members are replaced by copies in the new vertex order. New accessors
    /// are added in a fixed order (tangents, remapped attributes, normals, indices, then per
    /// target), which is the order they get in the file.
    fn edit_primitive(
        &mut self,
        scene: &Scene<'_>,
        primitive: &Node,
        topology: Topology,
        job: usize,
        c: &Computed,
        snorm: Option<TangentStorage>,
    ) -> Result<PrimitiveEdit, SceneError> {
        // Decoded accessors have no data in the file: the primitive's are all written anew.
        let keeps = c.keeps_vertices(topology) && !reads_decoded(primitive, scene.data.decoded);
        let painting = scene.painted.get(job).is_some();
        let refs = written_refs(&mut self.job_refs, job);
        let changes = &mut self.changes;
        let (tangent, _) = match refs.tangent {
            Some(added) => added,
            None => {
                let (added, pending) = add_tangents(changes, c, snorm);
                refs.pending_tangents = pending;
                *refs.tangent.insert(added)
            }
        };
        let mut edit = PrimitiveEdit {
            remove_draco: draco::extension(primitive).is_some(),
            ..PrimitiveEdit::default()
        };
        if !keeps {
            let attributes = primitive.get("attributes");
            edit.attributes = self.remap_members(scene, job, c, attributes, |key| {
                key == "TANGENT" || (painting && key == "COLOR_0")
            })?;
        }
        // The members still to come, TANGENT first: room for them once, where growing and
        // then fitting the list took two allocations for every primitive.
        let added = 1 + usize::from(c.tangents.normals.is_some()) + usize::from(painting);
        edit.attributes.reserve_exact(added);
        edit.attributes.push(("TANGENT".into(), tangent));
        self.add_vertex_order(&mut edit, job, c, keeps, topology);
        let targets = primitive
            .get("targets")
            .and_then(Node::as_array)
            .unwrap_or(&[]);
        edit.targets = targets
            .iter()
            .enumerate()
            .map(|(t, target)| {
                self.edit_target(scene, job, c, (t, target), keeps, snorm.map(|s| s.snorm))
            })
            .collect::<Result<_, _>>()?;
        self.paint(scene, job, &mut edit);
        // Kept until the scene is written, one per primitive: no room to spare.
        edit.attributes.shrink_to_fit();
        Ok(edit)
    }

    /// With debug colours, the edit that paints a primitive whose own tangents are kept: its
    /// members (TANGENT too) copied in the painted vertex order, COLOR_0 and the material.
    /// `None` without debug colours: a kept primitive is otherwise left as it is.
    fn paint_kept(
        &mut self,
        scene: &Scene<'_>,
        primitive: &Node,
        topology: Topology,
        job: usize,
        c: &Computed,
    ) -> Result<Option<PrimitiveEdit>, SceneError> {
        if scene.painted.get(job).is_none() {
            return Ok(None);
        }
        let keeps = c.keeps_vertices(topology) && !reads_decoded(primitive, scene.data.decoded);
        let mut edit = PrimitiveEdit {
            remove_draco: draco::extension(primitive).is_some(),
            ..PrimitiveEdit::default()
        };
        if !keeps {
            let attributes = primitive.get("attributes");
            edit.attributes =
                self.remap_members(scene, job, c, attributes, |key| key == "COLOR_0")?;
            let targets = primitive
                .get("targets")
                .and_then(Node::as_array)
                .unwrap_or(&[]);
            edit.targets = targets
                .iter()
                .map(|target| self.remap_members(scene, job, c, Some(target), |_| false))
                .collect::<Result<_, _>>()?;
        }
        self.add_vertex_order(&mut edit, job, c, keeps, topology);
        self.paint(scene, job, &mut edit);
        Ok(Some(edit))
    }

    /// The job's generated normals, and unless the vertices are kept, its index buffer (and a
    /// triangle list's mode).
    fn add_vertex_order(
        &mut self,
        edit: &mut PrimitiveEdit,
        job: usize,
        c: &Computed,
        keeps: bool,
        topology: Topology,
    ) {
        let split = &c.tangents.split;
        let refs = written_refs(&mut self.job_refs, job);
        let changes = &mut self.changes;
        if let Some(normals) = &c.tangents.normals {
            let r = *refs
                .normal
                .get_or_insert_with(|| changes.add_floats(normals, false));
            edit.attributes.push(("NORMAL".into(), r));
        }
        if !keeps {
            let r = *refs.indices.get_or_insert_with(|| {
                let indices = split.indices_for(c.geometry.indices.as_deref());
                changes.add_indices(&indices, split.source_vertex.len())
            });
            edit.indices = Some(r);
            edit.to_triangle_list = topology != Topology::Triangles;
        }
    }

    /// With debug colours, the job's COLOR_0 and the debug material (the first new one).
    fn paint(&mut self, scene: &Scene<'_>, job: usize, edit: &mut PrimitiveEdit) {
        let Some(painted) = scene.painted.get(job) else {
            return;
        };
        let refs = written_refs(&mut self.job_refs, job);
        let changes = &mut self.changes;
        let r = *refs
            .color
            .get_or_insert_with(|| changes.add_floats(&painted.colors, false));
        edit.attributes.push(("COLOR_0".into(), r));
        edit.material = Some(0);
    }

    /// One morph target's members: remapped like the base attributes, and its TANGENT deltas
    /// when the target moves POSITION or NORMAL.
    fn edit_target(
        &mut self,
        scene: &Scene<'_>,
        job: usize,
        c: &Computed,
        (t, target): (usize, &Node),
        keeps: bool,
        snorm: Option<Snorm>,
    ) -> Result<Vec<(Text, Ref)>, SceneError> {
        let delta = c.target_deltas.get(t).and_then(Option::as_ref);
        let mut set = Vec::new();
        if !keeps {
            let skip_tangent = delta.is_some();
            set = self.remap_members(scene, job, c, Some(target), |key| {
                skip_tangent && key == "TANGENT"
            })?;
        }
        if let Some(deltas) = delta {
            let changes = &mut self.changes;
            let refs = written_refs(&mut self.job_refs, job);
            let r = match refs.deltas.iter().find(|(target, _)| *target == t) {
                Some(&(_, r)) => r,
                None => {
                    let r = add_deltas(changes, deltas, snorm);
                    refs.deltas.push((t, r));
                    r
                }
            };
            set.push(("TANGENT".into(), r));
        }
        Ok(set)
    }

    /// The members of `object` (attribute name → accessor) as copies in the job's split vertex
    /// order, in the object's own order, leaving out those `skip` names.
    fn remap_members(
        &mut self,
        scene: &Scene<'_>,
        job: usize,
        c: &Computed,
        object: Option<&Node>,
        skip: impl Fn(&str) -> bool,
    ) -> Result<Vec<(Text, Ref)>, SceneError> {
        let mut members = Vec::new();
        for member in object.and_then(Node::as_object).unwrap_or(&[]) {
            if skip(&member.key) {
                continue;
            }
            let Some(index) = member.value.as_u64().and_then(|i| usize::try_from(i).ok()) else {
                continue;
            };
            let r = match self.remapped.get(&(job, index)) {
                Some(r) => *r,
                None => {
                    let r = self.changes.add_remapped(
                        scene.root,
                        scene.data,
                        index,
                        &c.tangents.split.source_vertex,
                        scene.max_vertices,
                        member.key == "POSITION",
                    )?;
                    self.remapped.insert((job, index), r);
                    r
                }
            };
            members.push((member.key.clone(), r));
        }
        Ok(members)
    }
}
