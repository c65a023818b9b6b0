//! What a caller may ask of the scene layer, and what it gets back: [`SceneOptions`] (with its
//! [`SceneLimits`] and [`OutputFormat`]) in, [`Processed`] out.
//!
//! The service's query string and the command line accept the same option values because both
//! parse them here: every value has one [`FromStr`] ([`Method`]'s is in the tangent core), and
//! [`SceneOptions::set`] maps the query's `key=value` pairs onto the fields. [`Choice`] lists a
//! type's accepted names with a line of help, so that the command line can show them in
//! `--help` without a mirror enum of its own.
//!
//! Adding an option: a field here, its parser and its row in [`QUERY_OPTIONS`] (the table behind
//! [`SceneOptions::set`] and the OpenAPI document's query parameters); then the flag in
//! `src/cli/mod.rs`.

use super::report::Report;
use std::fmt;
use std::str::FromStr;
use tspace_tangent::{Cancel, Method, NormalMode};

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

/// An option whose values are a fixed list of names: the enum, `ALL` (in the order help lists
/// them), `name` (what the command line, the query string and reports say), the one [`FromStr`]
/// the command line and the query string share, and its [`Choices`] with each value's help; all
/// from one table, so that a value cannot be parsed without being listed, or listed without help.
macro_rules! named_choices {
    (
        $(#[$meta:meta])*
        pub enum $enum:ident expecting $expected:literal {
            $( $(#[$variant_meta:meta])* $variant:ident => $name:literal, $help:literal; )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub enum $enum {
            $( $(#[$variant_meta])* $variant, )+
        }

        impl $enum {
            /// Every value, in the order help texts list them.
            pub const ALL: &'static [$enum] = &[$($enum::$variant),+];

            /// The name used on the command line, in query strings and in reports.
            pub fn name(self) -> &'static str {
                match self {
                    $( $enum::$variant => $name, )+
                }
            }
        }

        impl FromStr for $enum {
            type Err = Expected;

            fn from_str(name: &str) -> Result<$enum, Expected> {
                $enum::ALL
                    .iter()
                    .copied()
                    .find(|value| value.name() == name)
                    .ok_or(Expected($expected))
            }
        }

        impl Choices for $enum {
            fn choices() -> Vec<Choice> {
                vec![$( Choice { name: $name, aliases: &[], help: $help }, )+]
            }
        }
    };
}

named_choices! {
    /// The container to write. Its name is also the output file's extension.
    pub enum OutputFormat expecting "glb or gltf" {
        #[default]
        Glb => "glb", "Binary glTF, images embedded";
        /// `.gltf` JSON with the buffer embedded as a `data:` URI.
        GltfEmbedded => "gltf", "glTF JSON with its buffer embedded as a data: URI";
    }
}

named_choices! {
    /// The component type of the TANGENT tspace writes.
    pub enum TangentType expecting "auto or float" {
        /// The normals' own precision: normalized BYTE or SHORT where NORMAL is
        /// (KHR_mesh_quantization), float everywhere else.
        #[default]
        Auto => "auto", "The normals' precision: normalized byte or short where NORMAL is quantized, else float";
        /// Always float.
        Float => "float", "Always float";
    }
}

named_choices! {
    /// How the geometry tspace writes is stored.
    pub enum Compression expecting "auto, none or meshopt" {
        /// Compressed (`EXT_meshopt_compression`) when the input used meshopt compression, else
        /// the input's own layout.
        #[default]
        Auto => "auto", "EXT_meshopt_compression when the input used meshopt, else the input's layout";
        /// Uncompressed: meshopt-compressed views of the input are written out as plain data.
        None => "none", "Uncompressed: meshopt views of the input written out plain";
        /// `EXT_meshopt_compression`, whatever the input.
        Meshopt => "meshopt", "EXT_meshopt_compression, whatever the input";
    }
}

named_choices! {
    /// How normals are made for OBJ faces without `vn` (glTF primitives without `NORMAL` get
    /// flat normals, as the glTF specification requires, whatever this says).
    pub enum Normals expecting "auto, smooth or flat" {
        /// The OBJ's smoothing groups where it has `s` statements (smooth within a group, flat
        /// where `s` is off), else smooth by angle: what modelling tools do.
        #[default]
        Auto => "auto", "OBJ without vn: smooth within its s groups (flat where s off), or by angle where it has none";
        /// Smooth across edges flatter than the crease angle, smoothing groups ignored.
        Smooth => "smooth", "OBJ without vn: smooth across edges flatter than the crease angle, s groups ignored";
        /// One normal per face: faceted.
        Flat => "flat", "OBJ without vn: one normal per face (faceted)";
    }
}

named_choices! {
    /// Outputs for looking rather than shipping.
    pub enum Debug expecting "none or colors" {
        /// The processed scene as it should ship.
        #[default]
        None => "none", "The processed scene as it should ship";
        /// Every computed primitive painted by what tspace found in each triangle (COLOR_0
        /// and an unlit material): for looking in a viewer, never for shipping.
        Colors => "colors", "Paint each triangle by its finding (COLOR_0 and an unlit material), for looking in a viewer: never ship it";
    }
}

/// A crease angle in degrees, from 0 to 180: edges whose faces meet at more stay hard.
pub fn parse_angle(text: &str) -> Result<f32, Expected> {
    text.parse::<f32>()
        .ok()
        .filter(|a| (0.0..=180.0).contains(a))
        .ok_or(Expected("an angle in degrees from 0 to 180"))
}

/// A value outside the accepted ones; the message says what is accepted (callers add which
/// value was given, and where).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Expected(&'static str);

impl fmt::Display for Expected {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "expected {}", self.0)
    }
}

impl std::error::Error for Expected {}

/// A query string's boolean: empty (the bare key, `?overwrite`), `true`, `1`, `yes`, or
/// `false`, `0`, `no`. On the command line the same options are flags, present or not.
pub fn parse_switch(text: &str) -> Result<bool, Expected> {
    match text {
        "" | "true" | "1" | "yes" => Ok(true),
        "false" | "0" | "no" => Ok(false),
        _ => Err(Expected("true or false")),
    }
}

/// One accepted value of an option, for help texts.
pub struct Choice {
    pub name: &'static str,
    /// Other spellings the parser accepts, not listed in help.
    pub aliases: &'static [&'static str],
    pub help: &'static str,
}

/// An option type whose values are a fixed list of names, each parsed by its [`FromStr`].
pub trait Choices: FromStr + Copy + Send + Sync + 'static {
    /// Every value with its help, in the order help texts list them.
    fn choices() -> Vec<Choice>;
}

impl Choices for Method {
    fn choices() -> Vec<Choice> {
        Method::ALL
            .into_iter()
            .map(|m| Choice {
                name: m.name(),
                aliases: m.aliases(),
                help: match m {
                    Method::MikkTSpace => "MikkTSpace, what normal-map bakers use",
                    Method::Fast => "Faster and smooth, but not what bakers use",
                    Method::Axis => "Needs no texture coordinates (for OBJ files without `vt`)",
                },
            })
            .collect()
    }
}

/// What to do with a scene.
#[derive(Clone, Debug)]
pub struct SceneOptions {
    pub method: Method,
    /// Recompute tangents a primitive already has.
    pub overwrite: bool,
    /// Give tangents to every triangle primitive, whatever its material.
    pub all: bool,
    pub format: OutputFormat,
    /// For glTF primitives without normals (flat, as the glTF specification requires).
    pub normal_mode: NormalMode,
    /// For OBJ faces without `vn`.
    pub normals: Normals,
    /// The crease angle, in degrees, where OBJ normals are smoothed by angle.
    pub normals_angle: f32,
    /// Write the scene; `false` only analyses and reports.
    pub write: bool,
    /// The TANGENT's component type.
    pub tangents: TangentType,
    /// How the written geometry is stored.
    pub compress: Compression,
    /// An output for looking instead of the one to ship.
    pub debug: Debug,
    pub limits: SceneLimits,
    /// Set by whoever waits for the scene when they stop waiting (a request that timed out, a
    /// client that went away): the work stops between steps and inside the core, and the
    /// scene fails with a `timeout` error nobody reads.
    pub cancel: Cancel,
    /// Keep what a UV-layout picture draws ([`Processed::layouts`]); off unless a picture is
    /// asked for, since it holds a copy of the UVs and indices.
    pub layouts: bool,
    /// Return a written GLB as [`Processed::pieces`], which refer to the input where the output
    /// repeats it, instead of as one vector: for a caller that writes it out while it still
    /// holds the input (the command line). An OBJ's, whose GLB is made inside, comes back whole.
    pub in_pieces: bool,
    /// Called once the input's parse tree of a large document is freed, before the output's
    /// JSON is put together (see `gltf::write::RELEASE_FROM_JSON_BYTES`). That JSON is one
    /// block too large to come from the tree's freed memory, so a caller holds both at once
    /// unless it hands the tree's back here (the service and the command line do, see
    /// `crate::memory`). `None` keeps it.
    pub release_freed_memory: Option<fn()>,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            method: Method::MikkTSpace,
            overwrite: false,
            all: false,
            format: OutputFormat::Glb,
            normal_mode: NormalMode::Flat,
            normals: Normals::Auto,
            normals_angle: super::obj_gltf::DEFAULT_CREASE_DEGREES,
            write: true,
            tangents: TangentType::Auto,
            compress: Compression::Auto,
            debug: Debug::None,
            limits: SceneLimits::default(),
            cancel: Cancel::default(),
            layouts: false,
            in_pieces: false,
            release_freed_memory: None,
        }
    }
}

/// An option [`SceneOptions::set`] could not take.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OptionError {
    /// No option has this name.
    Unknown { key: String },
    /// The option exists but the value is not one it takes.
    Invalid {
        key: String,
        value: String,
        expected: String,
    },
}

impl fmt::Display for OptionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OptionError::Unknown { key } => {
                write!(f, "unknown option {key:?}; the options are ")?;
                let keys = SceneOptions::query_keys();
                let last = keys.len() - 1;
                for (i, name) in keys.enumerate() {
                    let separator = match i {
                        0 => "",
                        _ if i == last => " and ",
                        _ => ", ",
                    };
                    write!(f, "{separator}{name}")?;
                }
                Ok(())
            }
            OptionError::Invalid {
                key,
                value,
                expected,
            } => write!(f, "{key}={value:?}: {expected}"),
        }
    }
}

impl std::error::Error for OptionError {}

/// Sets one option from its text, or says what the option accepts.
type Setter = fn(&mut SceneOptions, &str) -> Result<(), String>;

/// What a query option takes, for documents that list the options (the OpenAPI document).
#[derive(Clone, Copy)]
pub enum OptionValues {
    /// A boolean, read by [`parse_switch`].
    Switch,
    /// An angle in degrees from 0 to 180, read by [`parse_angle`].
    Degrees,
    /// One of a fixed list of names: the type's name (`Method`) and its [`Choices`], the list
    /// its [`FromStr`] reads.
    OneOf {
        type_name: &'static str,
        choices: fn() -> Vec<Choice>,
    },
}

/// One option of the query string: its name, what it does and takes, and how it is read and
/// set. [`SceneOptions::set`], the "unknown option" message and the OpenAPI document all read
/// [`QUERY_OPTIONS`], so an option cannot be taken without being listed.
pub struct QueryOption {
    /// The name the query string gives it.
    pub key: &'static str,
    /// What it does, in one line.
    pub help: &'static str,
    pub values: OptionValues,
    /// Shapes only the written scene: accepted, and without effect, where nothing is written.
    pub output_only: bool,
    /// Its value in a [`SceneOptions`], as the query string spells it; on the defaults, its
    /// default.
    pub value_in: fn(&SceneOptions) -> String,
    set: Setter,
}

fn switch_name(on: bool) -> String {
    if on { "true" } else { "false" }.to_owned()
}

/// Every option [`SceneOptions::set`] takes, in the order messages and documents list them.
pub const QUERY_OPTIONS: [QueryOption; 9] = [
    QueryOption {
        key: "method",
        help: "How tangents are computed",
        values: OptionValues::OneOf {
            type_name: "Method",
            choices: <Method as Choices>::choices,
        },
        output_only: false,
        value_in: |o| o.method.name().to_owned(),
        set: |o, v| {
            o.method = v
                .parse()
                .map_err(|e: tspace_tangent::UnknownMethod| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "overwrite",
        help: "Recompute tangents a primitive already has, instead of auditing them",
        values: OptionValues::Switch,
        output_only: false,
        value_in: |o| switch_name(o.overwrite),
        set: |o, v| {
            o.overwrite = parse_switch(v).map_err(|e| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "all",
        help: "Give tangents to every triangle primitive, whatever its material",
        values: OptionValues::Switch,
        output_only: false,
        value_in: |o| switch_name(o.all),
        set: |o, v| {
            o.all = parse_switch(v).map_err(|e| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "format",
        help: "The container of the written scene",
        values: OptionValues::OneOf {
            type_name: "OutputFormat",
            choices: <OutputFormat as Choices>::choices,
        },
        output_only: true,
        value_in: |o| o.format.name().to_owned(),
        set: |o, v| {
            o.format = v.parse().map_err(|e: Expected| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "tangents",
        help: "The component type of the TANGENT written",
        values: OptionValues::OneOf {
            type_name: "TangentType",
            choices: <TangentType as Choices>::choices,
        },
        output_only: true,
        value_in: |o| o.tangents.name().to_owned(),
        set: |o, v| {
            o.tangents = v.parse().map_err(|e: Expected| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "compress",
        help: "How the written geometry is stored",
        values: OptionValues::OneOf {
            type_name: "Compression",
            choices: <Compression as Choices>::choices,
        },
        output_only: true,
        value_in: |o| o.compress.name().to_owned(),
        set: |o, v| {
            o.compress = v.parse().map_err(|e: Expected| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "debug",
        help: "colors writes a scene for looking, not shipping: each computed primitive painted by what tspace found in each triangle (COLOR_0 and an unlit material; vertices split where classes meet)",
        values: OptionValues::OneOf {
            type_name: "Debug",
            choices: <Debug as Choices>::choices,
        },
        output_only: true,
        value_in: |o| o.debug.name().to_owned(),
        set: |o, v| {
            o.debug = v.parse().map_err(|e: Expected| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "normals",
        help: "Normals for OBJ faces without vn. auto honours the OBJ's smoothing groups (smooth within an s group, flat where s is off) and, in a file without s statements, smooths across edges flatter than normals_angle, as modelling tools' importers do; smooth ignores the groups; flat is faceted. glTF primitives without NORMAL are always flat, as the glTF specification requires",
        values: OptionValues::OneOf {
            type_name: "Normals",
            choices: <Normals as Choices>::choices,
        },
        output_only: false,
        value_in: |o| o.normals.name().to_owned(),
        set: |o, v| {
            o.normals = v.parse().map_err(|e: Expected| e.to_string())?;
            Ok(())
        },
    },
    QueryOption {
        key: "normals_angle",
        help: "The crease angle of smooth OBJ normals, in degrees: edges sharper than this stay hard",
        values: OptionValues::Degrees,
        output_only: false,
        value_in: |o| o.normals_angle.to_string(),
        set: |o, v| {
            o.normals_angle = parse_angle(v).map_err(|e| e.to_string())?;
            Ok(())
        },
    },
];

impl SceneOptions {
    /// The options [`SceneOptions::set`] takes by name, as the query string names them.
    pub fn query_keys() -> impl ExactSizeIterator<Item = &'static str> {
        QUERY_OPTIONS.iter().map(|option| option.key)
    }

    /// Sets the option `key` from its text, as a query string gives it (already
    /// percent-decoded). Limits and `write` are the caller's, not the user's, and are not named.
    pub fn set(&mut self, key: &str, value: &str) -> Result<(), OptionError> {
        let Some(option) = QUERY_OPTIONS.iter().find(|option| option.key == key) else {
            return Err(OptionError::Unknown {
                key: key.to_owned(),
            });
        };
        (option.set)(self, value).map_err(|expected| OptionError::Invalid {
            key: key.to_owned(),
            value: value.to_owned(),
            expected,
        })
    }
}

/// The written scene (unless only analysed) and its report.
pub struct Processed {
    /// The written scene, unless only analysed or written in pieces.
    pub bytes: Option<Vec<u8>>,
    /// With [`SceneOptions::in_pieces`]: the written GLB, piece by piece.
    pub pieces: Option<super::pieces::Pieces>,
    pub report: Report,
    /// With [`SceneOptions::layouts`]: the texture layout of every geometry that was computed.
    pub layouts: Vec<super::layout::Layout>,
    /// How long each step took, in order: for benchmarks and profiling, never in the report
    /// (which must not change from run to run).
    pub timings: Timings,
}

/// Wall-clock time per step of one scene, in the order the steps ran.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    pub steps: Vec<(&'static str, std::time::Duration)>,
    last: Option<std::time::Instant>,
}

impl Timings {
    /// Starts the clock for the first step.
    pub fn start() -> Timings {
        Timings {
            steps: Vec::new(),
            last: Some(std::time::Instant::now()),
        }
    }

    /// Ends the step `name` (begun when the previous one ended) and starts the next.
    pub fn lap(&mut self, name: &'static str) {
        let now = std::time::Instant::now();
        if let Some(last) = self.last {
            self.steps.push((name, now - last));
        }
        self.last = Some(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Help lists only names the parser accepts, so the command line and the query string
    /// cannot drift apart.
    fn choices_parse_back<T: Choices + PartialEq + fmt::Debug>(name_of: fn(T) -> &'static str) {
        for choice in T::choices() {
            let Ok(value) = choice.name.parse::<T>() else {
                panic!("{} does not parse", choice.name);
            };
            assert_eq!(name_of(value), choice.name);
            for alias in choice.aliases {
                assert!(alias.parse::<T>().is_ok_and(|v| v == value), "{alias}");
            }
        }
    }

    #[test]
    fn every_listed_choice_parses_back() {
        choices_parse_back::<Method>(Method::name);
        choices_parse_back::<OutputFormat>(OutputFormat::name);
        choices_parse_back::<TangentType>(TangentType::name);
        choices_parse_back::<Compression>(Compression::name);
        choices_parse_back::<Normals>(Normals::name);
        choices_parse_back::<Debug>(Debug::name);
    }

    /// What a document lists for an option is what the setter takes, and reads back as set.
    #[test]
    fn every_listed_value_of_every_option_sets_and_reads_back() {
        for option in &QUERY_OPTIONS {
            let values: Vec<String> = match option.values {
                OptionValues::Switch => vec!["true".into(), "false".into()],
                OptionValues::Degrees => ["0", "45.5", "60", "180"].map(String::from).to_vec(),
                OptionValues::OneOf { choices, .. } => {
                    choices().iter().map(|c| c.name.to_owned()).collect()
                }
            };
            let default = (option.value_in)(&SceneOptions::default());
            assert!(values.contains(&default), "{}: {default}", option.key);
            for value in values {
                let mut options = SceneOptions::default();
                options.set(option.key, &value).unwrap();
                assert_eq!((option.value_in)(&options), value, "{}", option.key);
            }
        }
    }

    #[test]
    fn options_are_set_by_name_or_say_why_not() {
        let mut options = SceneOptions::default();
        for (key, value) in [
            ("method", "mikk"),
            ("overwrite", ""),
            ("all", "no"),
            ("format", "gltf"),
            ("compress", "meshopt"),
            ("normals", "flat"),
            ("normals_angle", "45.5"),
        ] {
            options.set(key, value).unwrap();
        }
        assert_eq!(options.method, Method::MikkTSpace);
        assert!(options.overwrite && !options.all);
        assert_eq!(options.format, OutputFormat::GltfEmbedded);
        assert_eq!(options.compress, Compression::Meshopt);
        assert_eq!(
            (options.normals, options.normals_angle),
            (Normals::Flat, 45.5)
        );
        let mut message = |key, value| options.set(key, value).unwrap_err().to_string();
        assert_eq!(
            message("method", "magic"),
            "method=\"magic\": expected mikktspace, fast or axis"
        );
        assert_eq!(
            message("overwrite", "maybe"),
            "overwrite=\"maybe\": expected true or false"
        );
        assert_eq!(
            message("format", "fbx"),
            "format=\"fbx\": expected glb or gltf"
        );
        assert_eq!(
            message("compress", "zip"),
            "compress=\"zip\": expected auto, none or meshopt"
        );
        assert_eq!(
            message("normals", "soft"),
            "normals=\"soft\": expected auto, smooth or flat"
        );
        for angle in ["-1", "181", "NaN", "inf", "sixty"] {
            assert_eq!(
                message("normals_angle", angle),
                format!("normals_angle={angle:?}: expected an angle in degrees from 0 to 180")
            );
        }
        assert_eq!(
            message("colour", "red"),
            "unknown option \"colour\"; the options are method, overwrite, all, format, tangents, compress, debug, normals and normals_angle"
        );
    }
}
