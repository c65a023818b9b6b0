//! The OpenAPI document (`GET /openapi.json`, Swagger UI at `/docs`), built from the code it
//! describes: the query parameters and their values from the option table the parser reads
//! ([`QUERY_OPTIONS`]), the error responses and the `Problem` schema from [`ProblemCode`] (see
//! [`super::problem`]), the report's schema from the report's own types. What has no Rust type
//! of its own, a scene file's bytes and the multipart bodies around them, is described here.
//!
//! The document is meant for client generators as much as for people: request and response
//! bodies are files (`type: string, format: binary`), options are enums, every error is
//! `application/problem+json`. `scripts/openapi-client-test` generates a Python client from it
//! and drives the service with that client.
//!
//! [`ProblemCode`]: crate::scene::error::ProblemCode

use super::problem::{Problem, ProblemCodes};
use super::routes;
use crate::scene::options::{OptionValues, QUERY_OPTIONS, QueryOption, SceneOptions};
use crate::scene::report::Report;
use std::borrow::Cow;
use utoipa::openapi::path::{Parameter, ParameterBuilder, ParameterIn};
use utoipa::openapi::schema::{
    AdditionalProperties, KnownFormat, Object, ObjectBuilder, SchemaFormat, Type,
};
use utoipa::openapi::{Header, OpenApi as Document, Ref, RefOr, Required, Schema};
use utoipa::{IntoParams, Modify, OpenApi, PartialSchema, ToSchema};

#[derive(OpenApi)]
#[openapi(
    info(
        title = "tspace",
        description = "Tangent frames for glTF, GLB and OBJ scenes: MikkTSpace-exact, with a report of what was found."
    ),
    paths(
        routes::tangents,
        routes::analyze,
        routes::uv_layout,
        routes::healthz,
        routes::readyz,
        routes::metrics,
        super::problem::problem_page
    ),
    components(schemas(Problem)),
    tags(
        (name = "scenes", description = "Tangents for a scene, or a report of what they would be"),
        (name = "service", description = "Health, readiness, metrics and the problem pages"),
    ),
    modifiers(&OptionSchemas, &ProblemCodes, &RequestIds, &ApiKeyScheme)
)]
pub struct ApiDoc;

/// The media types a scene is sent or answered as, besides `multipart/*`.
pub const SCENE_TYPES: [&str; 3] = ["model/gltf-binary", "model/gltf+json", "model/obj"];

/// `type: string, format: binary`: what generators turn into a file or a byte stream.
fn binary(description: &str) -> Object {
    ObjectBuilder::new()
        .schema_type(Type::String)
        .format(Some(SchemaFormat::KnownFormat(KnownFormat::Binary)))
        .description(Some(description))
        .build()
}

/// A scene file's bytes: a GLB, a `.gltf` or an OBJ.
pub struct SceneFile;

impl PartialSchema for SceneFile {
    fn schema() -> RefOr<Schema> {
        binary("A GLB, a .gltf or an OBJ file").into()
    }
}

impl ToSchema for SceneFile {
    fn name() -> Cow<'static, str> {
        "SceneFile".into()
    }
}

/// The scene with tangents, as `/v1/tangents` answers it: a GLB, or glTF JSON.
pub struct WrittenScene;

impl PartialSchema for WrittenScene {
    fn schema() -> RefOr<Schema> {
        binary(
            "The scene with tangents: a GLB, or (format=gltf) glTF JSON with its buffer embedded",
        )
        .into()
    }
}

impl ToSchema for WrittenScene {
    fn name() -> Cow<'static, str> {
        "WrittenScene".into()
    }
}

/// A `multipart/form-data` upload: the scene in the part `file`, and every file it refers to
/// (buffers, images, an OBJ's MTL) in a part of its own, named by its file name.
pub struct SceneUpload;

impl PartialSchema for SceneUpload {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::Object)
            .description(Some(
                "The scene in the part `file` (`scene` and `model` are read too; failing those, \
                 the first part whose file name ends in .glb, .gltf or .obj). Every other part is \
                 a file the scene refers to (a buffer, an image, an OBJ's MTL), matched by its \
                 file name (its field name when it has none).",
            ))
            .property("file", binary("The scene: a GLB, a .gltf or an OBJ"))
            .required("file")
            .additional_properties(Some(AdditionalProperties::RefOr(
                binary("A file the scene refers to, named by its file name").into(),
            )))
            .build()
            .into()
    }
}

impl ToSchema for SceneUpload {
    fn name() -> Cow<'static, str> {
        "SceneUpload".into()
    }
}

/// The `multipart/mixed` answer of `/v1/tangents` (with `Accept: multipart/mixed`): the report,
/// then the scene (see `super::mixed`).
pub struct ReportAndScene;

impl PartialSchema for ReportAndScene {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::Object)
            .description(Some(
                "Two parts: `report` (application/json), then `scene` (the scene with tangents, \
                 as a file named scene.glb or scene.gltf).",
            ))
            .property("report", Ref::from_schema_name(Report::name()))
            .property("scene", WrittenScene::schema())
            .required("report")
            .required("scene")
            .into()
    }
}

impl ToSchema for ReportAndScene {
    fn name() -> Cow<'static, str> {
        "ReportAndScene".into()
    }
}

/// The query parameters of `POST /v1/tangents`: every option.
pub struct TangentsQuery;

impl IntoParams for TangentsQuery {
    fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
        QUERY_OPTIONS.iter().map(query_parameter).collect()
    }
}

/// The query parameters of `POST /v1/analyze`: the options that shape the analysis (the others
/// are accepted there, and change nothing).
pub struct AnalyzeQuery;

impl IntoParams for AnalyzeQuery {
    fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
        QUERY_OPTIONS
            .iter()
            .filter(|option| !option.output_only)
            .map(query_parameter)
            .collect()
    }
}

/// The query parameters `POST /v1/uv-layout` has besides [`AnalyzeQuery`]'s.
pub struct PictureQuery;

impl IntoParams for PictureQuery {
    fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
        let string = |values: Option<&[&str]>, default: Option<&str>| -> RefOr<Schema> {
            let mut schema = ObjectBuilder::new().schema_type(Type::String);
            if let Some(values) = values {
                schema = schema.enum_values(Some(values.iter().copied()));
            }
            if let Some(default) = default {
                schema = schema.default(Some(default.into()));
            }
            schema.into()
        };
        let parameter = |name: &str, description: &str, schema: RefOr<Schema>| {
            ParameterBuilder::new()
                .name(name)
                .parameter_in(ParameterIn::Query)
                .required(Required::False)
                .description(Some(description))
                .schema(Some(schema))
                .build()
        };
        vec![
            parameter(
                "format",
                "The picture's format (here it names the picture, not a scene).",
                string(Some(&["svg", "png"]), Some("svg")),
            ),
            parameter(
                "mesh",
                "Draw only this mesh's primitives: its index in meshes, or its name.",
                string(None, None),
            ),
            parameter(
                "primitive",
                "With mesh: draw only this primitive of it (its index in the mesh's primitives).",
                ObjectBuilder::new()
                    .schema_type(Type::Integer)
                    .minimum(Some(0))
                    .into(),
            ),
        ]
    }
}

fn query_parameter(option: &QueryOption) -> Parameter {
    let schema: RefOr<Schema> = match option.values {
        OptionValues::Switch => {
            let default = (option.value_in)(&SceneOptions::default()) == "true";
            ObjectBuilder::new()
                .schema_type(Type::Boolean)
                .default(Some(default.into()))
                .into()
        }
        OptionValues::Degrees => {
            let default: f64 = (option.value_in)(&SceneOptions::default())
                .parse()
                .unwrap_or_default();
            ObjectBuilder::new()
                .schema_type(Type::Number)
                .minimum(Some(0.0))
                .maximum(Some(180.0))
                .default(Some(default.into()))
                .into()
        }
        OptionValues::OneOf { type_name, .. } => Ref::from_schema_name(type_name).into(),
    };
    ParameterBuilder::new()
        .name(option.key)
        .parameter_in(ParameterIn::Query)
        .required(Required::False)
        .description(Some(option.help))
        .schema(Some(schema))
        .build()
}

/// The schema of a named option type (`Method`, `OutputFormat`…): its names as an enum, each
/// explained, with the option's default.
fn choice_schema(
    option: &QueryOption,
    choices: fn() -> Vec<crate::scene::options::Choice>,
) -> Object {
    let choices = choices();
    let explained: Vec<String> = choices
        .iter()
        .map(|choice| {
            let aliases = match choice.aliases {
                [] => String::new(),
                aliases => format!(" (also {})", aliases.join(", ")),
            };
            format!("`{}`{aliases}: {}", choice.name, choice.help)
        })
        .collect();
    ObjectBuilder::new()
        .schema_type(Type::String)
        .description(Some(format!("{}. {}.", option.help, explained.join("; "))))
        .enum_values(Some(choices.iter().map(|choice| choice.name)))
        .default(Some((option.value_in)(&SceneOptions::default()).into()))
        .build()
}

/// Adds the option types' schemas, which the query parameters refer to by name.
struct OptionSchemas;

impl Modify for OptionSchemas {
    fn modify(&self, openapi: &mut Document) {
        let components = openapi.components.get_or_insert_with(Default::default);
        for option in &QUERY_OPTIONS {
            if let OptionValues::OneOf { type_name, choices } = option.values {
                components
                    .schemas
                    .insert(type_name.to_owned(), choice_schema(option, choices).into());
            }
        }
    }
}

/// Every response carries `X-Request-Id` (see `super::router`): added to each, so that no
/// route can be described without it.
struct RequestIds;

impl Modify for RequestIds {
    fn modify(&self, openapi: &mut Document) {
        let header = Header::builder()
            .schema(String::schema())
            .description(Some(
                "The request's own X-Request-Id when it sent one, else a per-process counter in \
                 eight hex digits; log lines about the request carry it",
            ))
            .build();
        for item in openapi.paths.paths.values_mut() {
            let operations = [&mut item.get, &mut item.post];
            for operation in operations.into_iter().flatten() {
                for response in operation.responses.responses.values_mut() {
                    if let RefOr::T(response) = response {
                        response
                            .headers
                            .insert("X-Request-Id".to_owned(), header.clone());
                    }
                }
            }
        }
    }
}

/// The scene routes take `Authorization: Bearer <key>`, required only when the service was
/// given a key file (`--api-keys-file`): described as an optional bearer scheme (an empty
/// requirement or the key), so that generated clients can send a key and need not.
struct ApiKeyScheme;

impl Modify for ApiKeyScheme {
    fn modify(&self, openapi: &mut Document) {
        use utoipa::openapi::security::{
            HttpAuthScheme, HttpBuilder, SecurityRequirement, SecurityScheme,
        };
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "api_key",
            SecurityScheme::Http(
                HttpBuilder::new()
                    .scheme(HttpAuthScheme::Bearer)
                    .description(Some(
                        "An API key from the service's --api-keys-file, when it has one; 401 \
                         unauthorized without it",
                    ))
                    .build(),
            ),
        );
        for (path, item) in openapi.paths.paths.iter_mut() {
            if !path.starts_with("/v1/") {
                continue;
            }
            if let Some(operation) = item.post.as_mut() {
                operation.security = Some(vec![
                    SecurityRequirement::default(),
                    SecurityRequirement::new("api_key", Vec::<String>::new()),
                ]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::{Value, json};

    fn document() -> Value {
        serde_json::to_value(ApiDoc::openapi()).unwrap()
    }

    /// Where the document is committed, and the command that writes it anew.
    const COMMITTED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/openapi.json");
    const BLESS: &str = "TSPACE_BLESS_OPENAPI";

    /// The contract as committed in `docs/openapi.json`: a change to what the service promises
    /// (a field, a type, a description, since a doc comment on a report field becomes one) is
    /// then a change to that file, seen in review, rather than one that passes unnoticed.
    #[test]
    fn the_document_is_the_one_committed_in_the_docs() {
        let mut text = ApiDoc::openapi().to_pretty_json().unwrap();
        text.push('\n');
        if std::env::var_os(BLESS).is_some() {
            std::fs::write(COMMITTED, &text).unwrap();
        }
        let committed = std::fs::read_to_string(COMMITTED).unwrap_or_default();
        let first_difference = committed
            .lines()
            .zip(text.lines())
            .enumerate()
            .find(|(_, (old, new))| old != new)
            .map(|(n, (old, new))| format!("line {}: committed {old:?}, now {new:?}", n + 1));
        assert!(
            committed == text,
            "the OpenAPI document is not docs/openapi.json ({}); if the change is meant, run \
             `{BLESS}=1 cargo test --lib the_document_is_the_one_committed` and commit the file",
            first_difference.unwrap_or_else(|| "lengths differ".into())
        );
    }

    #[test]
    fn the_parameters_are_the_option_table_and_the_content_encoding() {
        let api = document();
        for (route, output_too, own) in [
            ("/v1/tangents", true, &[][..]),
            ("/v1/analyze", false, &[][..]),
            ("/v1/uv-layout", false, &["format", "mesh", "primitive"][..]),
        ] {
            let names: Vec<&str> = api["paths"][route]["post"]["parameters"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|p| p["in"] == "query")
                .map(|p| p["name"].as_str().unwrap())
                .collect();
            let expected: Vec<&str> = own
                .iter()
                .copied()
                .chain(
                    QUERY_OPTIONS
                        .iter()
                        .filter(|o| output_too || !o.output_only)
                        .map(|o| o.key),
                )
                .collect();
            assert_eq!(names, expected, "{route}");
        }
        for route in ["/v1/tangents", "/v1/analyze", "/v1/uv-layout"] {
            let headers: Vec<&Value> = api["paths"][route]["post"]["parameters"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|p| p["in"] == "header")
                .collect();
            assert_eq!(headers.len(), 1, "{route}");
            assert_eq!(headers[0]["name"], json!("Content-Encoding"), "{route}");
            assert_eq!(headers[0]["required"], json!(false), "{route}");
        }
        let method = &api["components"]["schemas"]["Method"];
        assert_eq!(method["enum"], json!(["mikktspace", "fast", "axis"]));
        assert_eq!(method["default"], json!("mikktspace"));
        assert_eq!(
            api["components"]["schemas"]["OutputFormat"]["enum"],
            json!(["glb", "gltf"])
        );
    }

    #[test]
    fn scenes_are_files_in_and_out() {
        let api = document();
        let tangents = &api["paths"]["/v1/tangents"]["post"];
        let file = json!("binary");
        for media in SCENE_TYPES.iter().chain(&["application/octet-stream"]) {
            let schema = &tangents["requestBody"]["content"][media]["schema"];
            assert_eq!(schema["format"], file, "request {media}: {schema}");
        }
        let upload = &tangents["requestBody"]["content"]["multipart/form-data"]["schema"];
        assert_eq!(upload["$ref"], "#/components/schemas/SceneUpload");
        let upload = &api["components"]["schemas"]["SceneUpload"];
        assert_eq!(upload["required"], json!(["file"]));
        assert_eq!(upload["properties"]["file"]["format"], file);
        assert_eq!(upload["additionalProperties"]["format"], file);
        let ok = &tangents["responses"]["200"];
        assert_eq!(ok["content"]["model/gltf-binary"]["schema"]["format"], file);
        assert!(ok["headers"]["X-Tspace-Report"].is_object(), "{ok}");
        let mixed = &ok["content"]["multipart/mixed"]["schema"]["properties"];
        assert_eq!(mixed["report"]["$ref"], "#/components/schemas/Report");
        assert_eq!(mixed["scene"]["format"], file);
        let analyzed = &api["paths"]["/v1/analyze"]["post"]["responses"]["200"];
        let report = &analyzed["content"]["application/json"]["schema"];
        assert_eq!(report["$ref"], "#/components/schemas/Report");
        let summary = &api["components"]["schemas"]["Summary"]["properties"];
        assert!(summary["primitives"].is_object(), "{summary}");
        assert_eq!(
            api["paths"]["/v1/analyze"]["post"]["requestBody"]["content"],
            tangents["requestBody"]["content"],
            "both routes read a scene the same way"
        );
        // What utoipa made of Vec<u8> before: no body is an array (of bytes as numbers).
        for (path, item) in api["paths"].as_object().unwrap() {
            for operation in item.as_object().unwrap().values() {
                let responses = operation["responses"].as_object().unwrap().values();
                for body in responses.chain([&operation["requestBody"]]) {
                    for (media, content) in body["content"].as_object().into_iter().flatten() {
                        assert_ne!(content["schema"]["type"], "array", "{path} {media}");
                    }
                }
            }
        }
    }

    #[test]
    fn every_response_says_its_request_id_and_a_503_when_to_retry() {
        let api = document();
        for (path, item) in api["paths"].as_object().unwrap() {
            for (verb, operation) in item.as_object().unwrap() {
                for (status, response) in operation["responses"].as_object().unwrap() {
                    assert!(
                        response["headers"]["X-Request-Id"].is_object(),
                        "{verb} {path} {status}"
                    );
                }
            }
        }
        let busy = &api["paths"]["/v1/tangents"]["post"]["responses"]["503"];
        assert!(busy["headers"]["Retry-After"].is_object(), "{busy}");
    }

    /// The scene routes say they take a bearer key, and that it may be left out.
    #[test]
    fn the_scene_routes_take_an_optional_bearer_key() {
        let api = document();
        assert_eq!(
            api["components"]["securitySchemes"]["api_key"]["scheme"],
            "bearer"
        );
        for path in ["/v1/tangents", "/v1/analyze", "/v1/uv-layout"] {
            let security = &api["paths"][path]["post"]["security"];
            assert_eq!(
                security,
                &serde_json::json!([{}, {"api_key": []}]),
                "{path}"
            );
        }
        let probe = &api["paths"]["/healthz"]["get"];
        assert!(probe.is_object() && probe["security"].is_null(), "{probe}");
    }

    /// An analysis writes nothing, so it cannot be refused for its output's size.
    #[test]
    fn only_the_route_that_writes_lists_output_too_large() {
        let api = document();
        let too_large = |path: &str| {
            api["paths"][path]["post"]["responses"]["413"]["description"]
                .as_str()
                .unwrap_or_default()
                .to_owned()
        };
        assert!(too_large("/v1/tangents").contains("`output-too-large`"));
        let analyze = too_large("/v1/analyze");
        assert!(analyze.contains("`body-too-large`"), "{analyze}");
        assert!(!analyze.contains("`output-too-large`"), "{analyze}");
    }
}
