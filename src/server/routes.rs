//! The handlers: read the request (raw body or multipart), hand the scene to the worker pool,
//! and turn its answer into a response.

use super::encoding::{self, BodyFailure};
use super::held::HeldBody;
use super::mixed;
use super::openapi::{
    AnalyzeQuery, PictureQuery, ReportAndScene, SceneFile, SceneUpload, TangentsQuery, WrittenScene,
};
use super::pool::Reservation;
use super::problem::Problem;
use super::shed;
use super::{App, content_type};
use crate::scene::error::{ProblemCode, SceneError};
use crate::scene::input::{self, InputKind};
use crate::scene::options::Debug;
use crate::scene::pictures;
use crate::scene::pieces::Part;
use crate::scene::report::Report;
use crate::scene::uri::{PartSet, percent_decode};
use crate::scene::{OutputFormat, Processed, SceneLimits, SceneOptions};
use axum::body::{Body, Bytes};
use axum::extract::multipart::{Field, MultipartError};
use axum::extract::{FromRequest, Multipart, RawQuery, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use tokio::sync::OwnedSemaphorePermit;
use tspace_tangent::Cancel;

fn invalid_option(detail: String) -> Problem {
    Problem::new(ProblemCode::InvalidOption, detail)
}

/// The query options of both POST routes, parsed by the scene layer's own option parser (the
/// one the command line's values go through too). Limits and `write` are set per route.
fn parse_query(raw: Option<&str>) -> Result<SceneOptions, Problem> {
    let mut options = SceneOptions::default();
    for pair in raw.unwrap_or("").split('&').filter(|p| !p.is_empty()) {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        let value = percent_decode(&value.replace('+', " "))
            .map_err(|e| invalid_option(format!("{key}: {e}")))?;
        options
            .set(key, &value)
            .map_err(|e| invalid_option(e.to_string()))?;
    }
    Ok(options)
}

/// The scene and its named parts, as the request carried them.
struct Upload {
    kind: InputKind,
    /// The main file's name, when a multipart upload gave one.
    name: Option<String>,
    main: Bytes,
    parts: Vec<(String, Bytes)>,
}

fn media_type(headers: &HeaderMap) -> Option<String> {
    headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(|v| {
            v.split(';')
                .next()
                .unwrap_or("")
                .trim()
                .to_ascii_lowercase()
        })
}

/// Why a body or part is not taken as a scene.
enum NotAScene {
    /// Its declared media type is some other kind of file (`image/png`).
    Declared(String),
    /// Nothing declared, named or sniffed says GLB, glTF or OBJ.
    Unrecognized,
}

impl NotAScene {
    /// For a raw body: what to send instead, multipart included.
    fn of_body(self) -> Problem {
        let detail = match self {
            NotAScene::Declared(other) => format!(
                "{other} is not a scene; send model/gltf-binary, model/gltf+json, model/obj, multipart/form-data, or application/octet-stream to have the bytes sniffed"
            ),
            NotAScene::Unrecognized => "the body is neither GLB, glTF JSON nor OBJ text".to_owned(),
        };
        Problem::new(ProblemCode::UnsupportedMediaType, detail)
    }

    /// For a multipart upload's scene part: the body-level advice ("send multipart") would
    /// tell a user to do what they did, so say which part it was and what it must be.
    fn of_part(self, field_name: &str, file_name: Option<&str>) -> Problem {
        let part = match file_name {
            Some(file) => format!("the part {field_name:?} ({file:?})"),
            None => format!("the part {field_name:?}"),
        };
        let what = match self {
            NotAScene::Declared(media_type) => format!("{media_type}, not a scene"),
            NotAScene::Unrecognized => "neither GLB, glTF JSON nor OBJ text".to_owned(),
        };
        Problem::new(
            ProblemCode::UnsupportedMediaType,
            format!(
                "{part} is taken as the scene, but it is {what}: send the GLB, .gltf or OBJ as the part named file, and its buffers, images and MTL files as further parts named as the scene refers to them"
            ),
        )
    }
}

fn kind_of(
    declared: Option<&str>,
    name: Option<&str>,
    bytes: &[u8],
) -> Result<InputKind, NotAScene> {
    if let Some(kind) = declared.and_then(InputKind::from_media_type) {
        return Ok(kind);
    }
    if let Some(kind) = name.and_then(InputKind::from_file_name) {
        return Ok(kind);
    }
    match declared {
        None | Some("application/octet-stream" | "text/plain" | "") => {}
        Some(other) => return Err(NotAScene::Declared(other.to_owned())),
    }
    InputKind::sniff(bytes).ok_or(NotAScene::Unrecognized)
}

fn too_large(limit: usize) -> Problem {
    Problem::new(
        ProblemCode::BodyTooLarge,
        format!("the request body is over the limit of {limit} bytes"),
    )
}

/// The problem for a body that could not be read whole: over the limit, or (compressed) not
/// decodable; `otherwise` for anything else.
fn unreadable(
    error: &(dyn std::error::Error + 'static),
    limit: usize,
    otherwise: Problem,
) -> Problem {
    match encoding::body_failure(error) {
        BodyFailure::Undecodable(detail) => Problem::new(ProblemCode::MalformedEncoding, detail),
        BodyFailure::TooLarge => too_large(limit),
        BodyFailure::Other => otherwise,
    }
}

fn multipart_problem(error: &MultipartError, limit: usize) -> Problem {
    let otherwise = if error.status() == StatusCode::PAYLOAD_TOO_LARGE {
        too_large(limit)
    } else {
        Problem::new(ProblemCode::MalformedMultipart, error.body_text())
    };
    unreadable(error, limit, otherwise)
}

async fn read_upload(app: &App, request: Request) -> Result<Upload, Problem> {
    let limit = app.config.body_limit;
    // What the sender declares it sends: for a compressed body, the compressed length, which
    // is then no bound on the decoded body but still the best first guess of its size.
    let sent_length = content_length(request.headers());
    let request = encoding::decode_request(request)?;
    let headers = request.headers().clone();
    let declared_length = content_length(&headers);
    if declared_length.is_some_and(|n| n > limit as u64) {
        return Err(too_large(limit));
    }
    let media = media_type(&headers);
    if media.as_deref() == Some("multipart/form-data") {
        let mut multipart = Multipart::from_request(request, &())
            .await
            .map_err(|e| Problem::new(ProblemCode::MalformedMultipart, e.body_text()))?;
        let mut fields: Vec<(String, Option<String>, Option<String>, Bytes)> = Vec::new();
        let mut read_so_far = 0usize;
        loop {
            let field = match multipart.next_field().await {
                Ok(Some(field)) => field,
                Ok(None) => break,
                Err(e) => return Err(multipart_problem(&e, limit)),
            };
            let field_name = field.name().unwrap_or("").to_owned();
            let file_name = field.file_name().map(str::to_owned);
            let part_type = field.content_type().map(str::to_owned);
            let room = declared_length
                .or(sent_length)
                .and_then(|n| usize::try_from(n).ok())
                .unwrap_or(0)
                .saturating_sub(read_so_far);
            let bytes = match whole_field(field, room).await {
                Ok(bytes) => bytes,
                Err(e) => return Err(multipart_problem(&e, limit)),
            };
            read_so_far += bytes.len();
            fields.push((field_name, file_name, part_type, bytes));
        }
        // The scene is the field named file, scene or model; else the first .gltf, .glb or
        // .obj; else the first field.
        let main = fields
            .iter()
            .position(|(n, _, _, _)| matches!(n.as_str(), "file" | "scene" | "model"))
            .or_else(|| {
                fields.iter().position(|(_, f, _, _)| {
                    f.as_deref().and_then(InputKind::from_file_name).is_some()
                })
            })
            .or(if fields.is_empty() { None } else { Some(0) })
            .ok_or_else(|| {
                Problem::new(
                    ProblemCode::MissingFile,
                    "the multipart body has no parts; send the scene as a part named file",
                )
            })?;
        let (field_name, file_name, part_type, bytes) = fields.remove(main);
        let declared = part_type.filter(|t| t != "application/octet-stream");
        let kind = kind_of(declared.as_deref(), file_name.as_deref(), &bytes)
            .map_err(|e| e.of_part(&field_name, file_name.as_deref()))?;
        let parts = fields
            .into_iter()
            .map(|(name, file_name, _, bytes)| (file_name.unwrap_or(name), bytes))
            .collect();
        return Ok(Upload {
            kind,
            name: file_name,
            main: bytes,
            parts,
        });
    }
    let expected = sent_length.and_then(|n| usize::try_from(n).ok());
    let body = whole_body(request.into_body(), limit, expected.unwrap_or(0))
        .await
        // A broken connection too: its client will not hear the answer.
        .map_err(|e| unreadable(&*e, limit, too_large(limit)))?;
    if body.is_empty() {
        return Err(Problem::new(
            ProblemCode::MissingFile,
            "the request body is empty; send a GLB, a .gltf or an OBJ",
        ));
    }
    let kind = kind_of(media.as_deref(), None, &body).map_err(NotAScene::of_body)?;
    Ok(Upload {
        kind,
        name: None,
        main: body,
        parts: Vec::new(),
    })
}

/// A raw body, read whole into one buffer as its frames arrive, each frame freed once copied.
///
/// Collecting the frames first and joining them at the end (`axum::body::to_bytes`) holds the
/// body twice at the join; and the frames, allocated on the connection's thread, leave their
/// memory free but kept in that thread's arena, where the worker that parses the scene cannot
/// use it. For a 27 MB JSON-heavy scene that was 58 MB of the server's peak above the command
/// line's.
///
/// The buffer starts at the length the sender declares, but never above the allocator's
/// mapping threshold (see memory.rs): a sender that declares more than it sends can make us
/// hold no more than that, per request in flight. Below the threshold, growing by doubling from
/// nothing cost eight concurrent clients of DamagedHelmet (3.8 MB) 20–25 ms of p50 (70 against
/// 48–57 ms), the blocks of eight growing bodies interleaved in the heaps so that each growth
/// was a copy; above it a growth is a remap, not a copy. A compressed body starts at its
/// compressed length (`expected`), nobody declaring its decoded one.
async fn whole_body(body: Body, limit: usize, expected: usize) -> Result<Bytes, axum::BoxError> {
    use http_body_util::BodyExt;
    let mut whole = Vec::with_capacity(expected.min(limit).min(super::memory::MAPPED_FROM));
    let mut body = http_body_util::Limited::new(body, limit);
    while let Some(frame) = body.frame().await {
        if let Ok(data) = frame?.into_data() {
            whole.extend_from_slice(&data);
        }
    }
    Ok(Bytes::from(whole))
}

/// The `Content-Length` a request declares, if it declares one that reads as a number.
pub(super) fn content_length(headers: &HeaderMap) -> Option<u64> {
    headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
}

/// A multipart field's data, read into one buffer as its chunks arrive.
///
/// The buffer starts as [`whole_body`]'s does, at what is left of the length the body declares
/// (`room`; no part can be longer), capped at the mapping threshold, for the same reason:
/// `Field::bytes` grows its buffer from nothing, and eight clients uploading one at a time
/// copy their buffers at every doubling. A part shorter than its buffer gives the rest back
/// (in place: a heap block shrinks where it lies, a mapped one is remapped).
async fn whole_field(mut field: Field<'_>, room: usize) -> Result<Bytes, MultipartError> {
    let mut whole = Vec::with_capacity(room.min(super::memory::MAPPED_FROM));
    while let Some(chunk) = field.chunk().await? {
        whole.extend_from_slice(&chunk);
    }
    whole.shrink_to_fit();
    Ok(Bytes::from(whole))
}

/// What an accepted scene request holds: its in-flight slot (until its answer is sent) and its
/// place in the pool (until its job is done).
struct Admitted<'a> {
    permit: OwnedSemaphorePermit,
    place: Reservation<'a>,
}

/// A slot and a place for a scene request, or the 503 when the pool has no place or as many
/// requests as `in_flight` allows are in progress: then the request is refused before its body
/// is read.
async fn admit(app: &App, request: Request) -> Result<(Request, Admitted<'_>), Box<Response>> {
    let Ok(permit) = Arc::clone(&app.in_flight).try_acquire_owned() else {
        return Err(Box::new(shed::refuse(app, request).await));
    };
    match app.pool.reserve() {
        Ok(place) => Ok((request, Admitted { permit, place })),
        Err(_) => Err(Box::new(shed::refuse(app, request).await)),
    }
}

/// [`read_upload`] within the request timeout, so that a client trickling its body in
/// (slowloris) holds a connection, never a worker, and not for long.
async fn read_upload_in_time(app: &App, request: Request) -> Result<Upload, Problem> {
    let upload = tokio::time::timeout(app.config.read_timeout, read_upload(app, request)).await;
    match upload {
        Ok(Err(refused)) if refused.code == ProblemCode::BodyTooLarge => {
            // What was read up to the limit is freed by now; see memory.rs.
            crate::memory::give_back_freed_memory();
            Err(refused)
        }
        Ok(upload) => upload,
        Err(_) => {
            app.metrics.reject("slow_upload");
            Err(Problem::new(
                ProblemCode::RequestTimeout,
                format!(
                    "the request body did not arrive within {:.1} s",
                    app.config.read_timeout.as_secs_f64()
                ),
            ))
        }
    }
}

/// The answer to a request whose options are refused before its upload is read.
async fn refuse_unread(app: &App, request: Request, problem: Problem) -> Response {
    shed::answer_unread(app, request, problem.into_response(), shed::Drain::Always).await
}

/// Admits a scene request and reads its upload, or the answer when either cannot be had: the
/// 503 of a refusal, or the problem with the body (one over the limit answered while the client
/// may still be sending it).
async fn accept(app: &App, request: Request) -> Result<(Upload, Admitted<'_>), Box<Response>> {
    let (request, admitted) = admit(app, request).await?;
    match read_upload_in_time(app, request).await {
        Ok(upload) => Ok((upload, admitted)),
        Err(problem) if problem.code == ProblemCode::BodyTooLarge => Err(Box::new(
            shed::closing_after_linger(problem.into_response()),
        )),
        Err(problem) => Err(Box::new(problem.into_response())),
    }
}

/// Cancels a scene's work when the request stops waiting for it: [`run`] returns early with a
/// 504, or the handler is dropped because its client went away. Then the worker is free within
/// one step of the work, and a job still queued is dropped when its turn comes.
struct CancelWhenDropped(Cancel);

impl Drop for CancelWhenDropped {
    fn drop(&mut self) {
        // Once the job has answered this changes nothing.
        self.0.cancel();
    }
}

/// Runs the scene on the pool, within the time limit.
async fn run(
    app: &Arc<App>,
    place: Reservation<'_>,
    upload: Upload,
    options: SceneOptions,
) -> Result<Processed, Problem> {
    run_then(app, place, upload, options, |processed, _| Ok(processed)).await
}

/// [`run`], then `then` on the worker with what it made (a picture drawn from the scene is
/// work for the pool too).
async fn run_then<T, F>(
    app: &Arc<App>,
    place: Reservation<'_>,
    upload: Upload,
    options: SceneOptions,
    then: F,
) -> Result<T, Problem>
where
    T: Send + 'static,
    F: FnOnce(Processed, &Bytes) -> Result<T, Problem> + Send + 'static,
{
    let _cancel_when_dropped = CancelWhenDropped(options.cancel.clone());
    let metrics_app = Arc::clone(app);
    let mut upload = upload;
    let job = move || {
        let cancelled = || {
            let cancelled = options.cancel.is_cancelled();
            if cancelled {
                metrics_app
                    .metrics
                    .jobs_cancelled
                    .fetch_add(1, Ordering::Relaxed);
            }
            cancelled
        };
        if cancelled() {
            return Err(Problem::from(SceneError::cancelled()));
        }
        let mut parts = PartSet::new();
        for (name, bytes) in &upload.parts {
            if let Err(e) = parts.insert(name.clone(), bytes) {
                return Err(Problem::new(ProblemCode::MalformedMultipart, e.to_string()));
            }
        }
        let result = match upload.kind {
            // An OBJ's text is not needed once read: the body that holds it (a hundred
            // megabytes for a million-triangle OBJ) is freed before the conversion needs as
            // much again. Nothing the rest makes refers to it, so `then` gets an empty body.
            InputKind::Obj => input::read_obj(&upload.main, &options).and_then(|read| {
                upload.main = Bytes::new();
                input::process_read_obj(read, &parts, &options)
            }),
            kind => input::process(kind, &upload.main, &parts, &options),
        };
        let processed = match result {
            Ok(processed) => processed,
            Err(e) => {
                cancelled();
                return Err(Problem::from(e));
            }
        };
        let summary = &processed.report.summary;
        let counted = (summary.triangles, summary.vertices_added);
        then(processed, &upload.main).map(|made| (made, counted))
    };
    let (made, (triangles, vertices_added)) = run_job(app, place, job).await??;
    app.metrics
        .triangles
        .fetch_add(triangles, Ordering::Relaxed);
    app.metrics
        .vertices_added
        .fetch_add(vertices_added, Ordering::Relaxed);
    Ok(made)
}

/// Runs `job` in its place on the worker pool within the request timeout: 504 when the time is
/// up, 500 when the job panics (the pool carries on).
async fn run_job<T, F>(app: &Arc<App>, place: Reservation<'_>, job: F) -> Result<T, Problem>
where
    T: Send + 'static,
    F: FnOnce() -> T + Send + 'static,
{
    let receiver = place.submit(job);
    match tokio::time::timeout(app.config.timeout, receiver).await {
        Err(_) => {
            app.metrics.reject("timeout");
            Err(Problem::new(
                ProblemCode::Timeout,
                format!(
                    "the scene took longer than {}",
                    in_seconds(app.config.timeout)
                ),
            ))
        }
        Ok(Err(_)) => Err(internal("the worker went away")),
        Ok(Ok(Err(panic))) => Err(internal(&panic.0)),
        Ok(Ok(Ok(result))) => Ok(result),
    }
}

/// A timeout as people write it: "30 s", "1.5 s", "0.02 s" (whole seconds printed alone, which
/// printed a 20 ms timeout as "0 s").
fn in_seconds(duration: std::time::Duration) -> String {
    let fraction = format!("{:.3}", duration.as_secs_f64());
    let trimmed = fraction.trim_end_matches('0').trim_end_matches('.');
    format!("{trimmed} s")
}

fn internal(cause: &str) -> Problem {
    tracing::error!(cause, "a job failed unexpectedly");
    Problem::new(
        ProblemCode::Internal,
        "tspace failed unexpectedly on this scene; the error was logged",
    )
}

fn scene_options(app: &App, query: &SceneOptions, write: bool) -> SceneOptions {
    SceneOptions {
        write,
        limits: SceneLimits {
            max_triangles: app.config.max_triangles,
            ..SceneLimits::default()
        },
        cancel: Cancel::new(),
        release_freed_memory: Some(crate::memory::give_back_freed_memory),
        ..query.clone()
    }
}

fn wants_multipart(headers: &HeaderMap) -> bool {
    headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.to_ascii_lowercase().contains("multipart/mixed"))
}

/// Adds tangents to a scene.
///
/// Answers with the scene, tangents added where its materials need them (GLB, or glTF JSON with
/// `format=gltf`), and the report's summary in `X-Tspace-Report`; with `Accept: multipart/mixed`,
/// with the full report, then the scene.
#[utoipa::path(
    post,
    path = "/v1/tangents",
    tag = "scenes",
    params(
        TangentsQuery,
        ("Content-Encoding" = Option<String>, Header, description = "gzip (or x-gzip) or zstd for a compressed body; it is decoded as it arrives, and the body limit counts decoded bytes. Another coding is 415 unsupported-encoding."),
    ),
    request_body(
        description = "A GLB, a .gltf or an OBJ as the whole body, its kind from the Content-Type (model/gltf-binary, model/gltf+json, model/obj or text/x-obj) or, with application/octet-stream, text/plain or none, sniffed; or multipart/form-data with the scene and the files it refers to.",
        content(
            (inline(SceneFile) = "model/gltf-binary"),
            (inline(SceneFile) = "model/gltf+json"),
            (inline(SceneFile) = "model/obj"),
            (inline(SceneFile) = "application/octet-stream"),
            (SceneUpload = "multipart/form-data", encoding(
                ("file" = (content_type = "model/gltf-binary, model/gltf+json, model/obj, application/octet-stream")),
            )),
        )
    ),
    responses(
        (status = 200, description = "The scene with tangents: GLB, or glTF JSON with format=gltf; with Accept: multipart/mixed, the full report, then the scene.",
            headers(("X-Tspace-Report" = String, description = "The report's summary as one line of JSON: a Summary, the `summary` of the Report (absent from a multipart/mixed answer, which holds the whole report)")),
            content(
                (inline(WrittenScene) = "model/gltf-binary"),
                (inline(WrittenScene) = "model/gltf+json"),
                (inline(ReportAndScene) = "multipart/mixed", encoding(
                    ("report" = (content_type = "application/json")),
                    ("scene" = (content_type = "model/gltf-binary, model/gltf+json")),
                )),
            )
        ),
        // The error responses are added from ProblemCode by ProblemCodes.
    )
)]
pub async fn tangents(
    State(app): State<Arc<App>>,
    RawQuery(raw): RawQuery,
    request: Request,
) -> Result<Response, Problem> {
    let query = match parse_query(raw.as_deref()) {
        Ok(query) => query,
        Err(problem) => return Ok(refuse_unread(&app, request, problem).await),
    };
    let multipart = wants_multipart(request.headers());
    let (upload, Admitted { permit, place }) = match accept(&app, request).await {
        Ok(accepted) => accepted,
        Err(answer) => return Ok(*answer),
    };
    // The answer is sent as the pieces the scene was written in: the upload's own bytes where
    // the output repeats them, and the new data, never put together in one buffer.
    let options = SceneOptions {
        in_pieces: true,
        ..scene_options(&app, &query, true)
    };
    let (processed, parts) = run_then(&app, place, upload, options, |mut processed, main| {
        let parts = answer_parts(&mut processed, main)?;
        Ok((processed, parts))
    })
    .await?;
    let scene_type = match query.format {
        OutputFormat::Glb => "model/gltf-binary",
        OutputFormat::GltfEmbedded => "model/gltf+json",
    };
    if multipart {
        // A debug scene is named so that nobody takes it for the one to ship.
        let file_name = match (query.format, query.debug) {
            (OutputFormat::Glb, Debug::None) => "scene.glb",
            (OutputFormat::GltfEmbedded, Debug::None) => "scene.gltf",
            (OutputFormat::Glb, Debug::Colors) => "scene.debug.glb",
            (OutputFormat::GltfEmbedded, Debug::Colors) => "scene.debug.gltf",
        };
        let report = processed.report.to_json_pretty();
        let mixed = mixed::report_and_scene(&report, parts, scene_type, file_name);
        let mut response = Response::new(Body::new(HeldBody::from_parts(mixed.parts, permit)));
        if let Ok(value) = HeaderValue::from_str(&mixed.content_type) {
            response.headers_mut().insert(header::CONTENT_TYPE, value);
        }
        return Ok(response);
    }
    let mut response = Response::new(Body::new(HeldBody::from_parts(parts, permit)));
    let headers = response.headers_mut();
    let (name, value) = content_type(scene_type);
    headers.insert(name, value);
    if let Ok(value) = HeaderValue::from_str(&processed.report.summary_line()) {
        headers.insert("x-tspace-report", value);
    }
    Ok(response)
}

/// The written scene as the parts of an answer: its pieces, the upload's own bytes sliced where
/// the output repeats them (no copy), or the one vector it was written as.
fn answer_parts(processed: &mut Processed, main: &Bytes) -> Result<Vec<Bytes>, Problem> {
    let Some(pieces) = processed.pieces.take() else {
        return Ok(vec![Bytes::from(
            processed.bytes.take().unwrap_or_default(),
        )]);
    };
    let (parts, own_input) = pieces.into_parts();
    // An OBJ's pieces refer to the GLB it was converted to, which they hold.
    let input = own_input.map_or_else(|| main.clone(), Bytes::from);
    parts
        .into_iter()
        .map(|part| match part {
            Part::Owned(bytes) => Ok(Bytes::from(bytes)),
            Part::Floats(floats) => Ok(Bytes::from_owner(floats)),
            Part::Input(range) if range.end <= input.len() => Ok(input.slice(range)),
            Part::Input(range) => Err(Problem::new(
                ProblemCode::Internal,
                format!("the written scene refers to bytes {range:?} beyond the upload"),
            )),
        })
        .collect()
}

/// Reports what `/v1/tangents` would do, without writing a scene.
#[utoipa::path(
    post,
    path = "/v1/analyze",
    tag = "scenes",
    params(
        AnalyzeQuery,
        ("Content-Encoding" = Option<String>, Header, description = "gzip (or x-gzip) or zstd for a compressed body; it is decoded as it arrives, and the body limit counts decoded bytes. Another coding is 415 unsupported-encoding."),
    ),
    request_body(
        description = "As for /v1/tangents: a GLB, a .gltf or an OBJ as the whole body, or multipart/form-data with the scene and the files it refers to.",
        content(
            (inline(SceneFile) = "model/gltf-binary"),
            (inline(SceneFile) = "model/gltf+json"),
            (inline(SceneFile) = "model/obj"),
            (inline(SceneFile) = "application/octet-stream"),
            (SceneUpload = "multipart/form-data", encoding(
                ("file" = (content_type = "model/gltf-binary, model/gltf+json, model/obj, application/octet-stream")),
            )),
        )
    ),
    responses(
        (status = 200, description = "The full JSON report", body = Report, content_type = "application/json"),
        // The error responses are added from ProblemCode by ProblemCodes.
    )
)]
pub async fn analyze(
    State(app): State<Arc<App>>,
    RawQuery(raw): RawQuery,
    request: Request,
) -> Result<Response, Problem> {
    let query = match parse_query(raw.as_deref()) {
        Ok(query) => query,
        Err(problem) => return Ok(refuse_unread(&app, request, problem).await),
    };
    let (upload, Admitted { permit, place }) = match accept(&app, request).await {
        Ok(accepted) => accepted,
        Err(answer) => return Ok(*answer),
    };
    let processed = run(&app, place, upload, scene_options(&app, &query, false)).await?;
    let report = processed.report.to_json_pretty();
    let mut response = Response::new(Body::new(HeldBody::new(report, permit)));
    let (name, value) = content_type("application/json");
    response.headers_mut().insert(name, value);
    Ok(response)
}

/// Draws the texture layout of a scene's geometry.
///
/// Every primitive that gets tangents from texture coordinates (or, with `mesh` and `primitive`,
/// the chosen ones) drawn in UV space: triangles filled by what tspace found in them (mirrored,
/// zero UV area, degenerate), repaired tangents outlined, handedness flips dotted, with a
/// legend whose counts are the report's. SVG by default, or PNG.
#[utoipa::path(
    post,
    path = "/v1/uv-layout",
    tag = "scenes",
    params(
        PictureQuery,
        AnalyzeQuery,
        ("Content-Encoding" = Option<String>, Header, description = "gzip (or x-gzip) or zstd for a compressed body; it is decoded as it arrives, and the body limit counts decoded bytes. Another coding is 415 unsupported-encoding."),
    ),
    request_body(
        description = "As for /v1/analyze: a GLB, a .gltf or an OBJ as the whole body, or multipart/form-data with the scene and the files it refers to.",
        content(
            (inline(SceneFile) = "model/gltf-binary"),
            (inline(SceneFile) = "model/gltf+json"),
            (inline(SceneFile) = "model/obj"),
            (inline(SceneFile) = "application/octet-stream"),
            (SceneUpload = "multipart/form-data", encoding(
                ("file" = (content_type = "model/gltf-binary, model/gltf+json, model/obj, application/octet-stream")),
            )),
        )
    ),
    responses(
        (status = 200, description = "The picture", content(
            (inline(SceneFile) = "image/svg+xml"),
            (inline(SceneFile) = "image/png"),
        )),
        // The error responses are added from ProblemCode by ProblemCodes.
    )
)]
pub async fn uv_layout(
    State(app): State<Arc<App>>,
    RawQuery(raw): RawQuery,
    request: Request,
) -> Result<Response, Problem> {
    let (scene_query, picture) = match parse_picture_query(raw.as_deref()) {
        Ok(parsed) => parsed,
        Err(problem) => return Ok(refuse_unread(&app, request, problem).await),
    };
    let (upload, Admitted { permit, place }) = match accept(&app, request).await {
        Ok(accepted) => accepted,
        Err(answer) => return Ok(*answer),
    };
    let file = upload
        .name
        .clone()
        .unwrap_or_else(|| format!("upload.{}", upload.kind.name()));
    let options = SceneOptions {
        layouts: true,
        ..scene_options(&app, &scene_query, false)
    };
    let format = picture.format;
    let drawn = run_then(&app, place, upload, options, move |processed, _| {
        pictures::draw(
            &pictures::Subject { file: &file },
            &processed.layouts,
            &picture.selection,
            format,
        )
        .map_err(Problem::from)
    })
    .await?;
    let mut response = Response::new(Body::new(HeldBody::new(drawn, permit)));
    let (name, value) = content_type(format.media_type());
    response.headers_mut().insert(name, value);
    Ok(response)
}

/// What `/v1/uv-layout` takes besides the scene options.
struct PictureChoice {
    format: pictures::PictureFormat,
    selection: pictures::Selection,
}

/// The scene options and the picture's own (`format`, `mesh`, `primitive`; `format` names the
/// picture here, not the scene's output).
fn parse_picture_query(raw: Option<&str>) -> Result<(SceneOptions, PictureChoice), Problem> {
    let mut scene = Vec::new();
    let (mut format, mut mesh, mut primitive) = (None, None, None);
    for pair in raw.unwrap_or("").split('&').filter(|p| !p.is_empty()) {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        let decoded = || {
            percent_decode(&value.replace('+', " "))
                .map_err(|e| invalid_option(format!("{key}: {e}")))
        };
        match key {
            "format" => format = Some(decoded()?),
            "mesh" => mesh = Some(decoded()?),
            "primitive" => primitive = Some(decoded()?),
            _ => scene.push(pair),
        }
    }
    let options = parse_query(Some(&scene.join("&")))?;
    let format = format
        .as_deref()
        .map(str::parse::<pictures::PictureFormat>)
        .transpose()
        .map_err(|e| invalid_option(format!("format: {e}")))?
        .unwrap_or_default();
    let selection = pictures::Selection::parse(mesh.as_deref(), primitive.as_deref())
        .map_err(invalid_option)?;
    Ok((options, PictureChoice { format, selection }))
}

/// Liveness: the process answers.
#[utoipa::path(get, path = "/healthz", tag = "service", responses(
    (status = 200, description = "ok", body = String, content_type = "text/plain")
))]
pub async fn healthz() -> &'static str {
    "ok\n"
}

/// Readiness: accepting work (not shutting down, queue not full).
#[utoipa::path(get, path = "/readyz", tag = "service", responses(
    (status = 200, description = "ready", body = String, content_type = "text/plain"),
    (status = 503, description = "shutting down or saturated", body = String, content_type = "text/plain")
))]
pub async fn readyz(State(app): State<Arc<App>>) -> Response {
    if app.draining.load(Ordering::Acquire) {
        return (StatusCode::SERVICE_UNAVAILABLE, "shutting down\n").into_response();
    }
    if app.pool.queued() >= app.config.queue && app.pool.running() >= app.config.concurrency {
        return (StatusCode::SERVICE_UNAVAILABLE, "saturated\n").into_response();
    }
    (StatusCode::OK, "ready\n").into_response()
}

/// Prometheus metrics.
#[utoipa::path(get, path = "/metrics", tag = "service", responses(
    (status = 200, description = "Prometheus text format", body = String, content_type = "text/plain")
))]
pub async fn metrics(State(app): State<Arc<App>>) -> Response {
    let text = app.metrics.render(app.pool.queued(), app.pool.running());
    let mut response = Response::new(Body::from(text));
    let (name, value) = content_type("text/plain; version=0.0.4; charset=utf-8");
    response.headers_mut().insert(name, value);
    response
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ServerConfig;
    use tspace_tangent::Method;

    #[test]
    fn timeouts_read_in_seconds_with_their_fraction() {
        use std::time::Duration;
        for (duration, text) in [
            (Duration::from_secs(30), "30 s"),
            (Duration::from_millis(1500), "1.5 s"),
            (Duration::from_millis(20), "0.02 s"),
            (Duration::from_millis(1), "0.001 s"),
            (Duration::from_secs(600), "600 s"),
        ] {
            assert_eq!(in_seconds(duration), text);
        }
    }

    #[tokio::test]
    async fn a_panicking_job_is_a_500_and_the_pool_serves_on() {
        let config = ServerConfig {
            concurrency: 1,
            queue: 0,
            ..ServerConfig::local()
        };
        let app = Arc::new(App::new(config).unwrap());
        let place = app.pool.reserve().unwrap();
        let problem = run_job(&app, place, || -> u8 { panic!("index out of bounds") })
            .await
            .err()
            .unwrap();
        assert_eq!((problem.status, problem.code), (500, ProblemCode::Internal));
        assert!(
            !problem.detail.contains("index out of bounds"),
            "no internals leak"
        );
        let place = app.pool.reserve().unwrap();
        assert_eq!(run_job(&app, place, || 5u8).await.unwrap(), 5);
    }

    #[test]
    fn options_parse_or_say_why_not() {
        let q = parse_query(Some("method=fast&overwrite&all=false&format=gltf")).unwrap();
        assert_eq!(q.method, Method::Fast);
        assert!(q.overwrite && !q.all);
        assert_eq!(q.format, OutputFormat::GltfEmbedded);
        for bad in [
            "method=magic",
            "overwrite=maybe",
            "format=fbx",
            "colour=red",
        ] {
            let problem = parse_query(Some(bad)).err().unwrap();
            assert_eq!(problem.code, "invalid-option", "{bad}");
        }
    }
}
