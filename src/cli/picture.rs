//! `tspace uv-layout`: one scene's texture layout drawn as an SVG or a PNG, the picture
//! `POST /v1/uv-layout` answers with (the same scene-layer call draws both).

use super::batch::{read_and_process, write_output};
use super::outcome::{Failure, failure_line};
use super::stdio::is_dash;
use super::{Exit, UvLayoutArgs, usage_error};
use crate::scene::pictures::{self, PictureFormat, Selection};
use crate::scene::{OutputFormat, SceneOptions};
use std::path::{Path, PathBuf};

pub(crate) fn uv_layout(args: UvLayoutArgs) -> Exit {
    let (format, output) = match destination(&args) {
        Ok(destination) => destination,
        Err(message) => return usage_error("uv-layout", message),
    };
    let selection = match Selection::parse(args.mesh.as_deref(), args.primitive.as_deref()) {
        Ok(selection) => selection,
        Err(message) => return usage_error("uv-layout", message),
    };
    let options = SceneOptions {
        layouts: true,
        ..args.scene.scene_options(OutputFormat::Glb, false)
    };
    let drawn = read_and_process(&args.input, &options).and_then(|processed| {
        let file = file_name(&args.input);
        pictures::draw(
            &pictures::Subject { file: &file },
            &processed.layouts,
            &selection,
            format,
        )
        .map_err(Failure::from)
    });
    let written = drawn.and_then(|bytes| write_output(&output, &bytes));
    match written {
        Ok(()) => {
            if !args.quiet && !is_dash(&output) {
                eprintln!("tspace: wrote {}", output.display());
            }
            Exit::Ok
        }
        Err(failure) => {
            eprintln!("{}", failure_line(&args.input, &failure));
            failure.exit
        }
    }
}

/// The picture's format and where it goes: `-o` (its extension naming the format unless
/// `--format` does), else `<stem>.uv.svg` (or `.png`) beside the input.
fn destination(args: &UvLayoutArgs) -> Result<(PictureFormat, PathBuf), String> {
    let named = args
        .output
        .as_deref()
        .filter(|o| !is_dash(o))
        .and_then(|o| {
            let extension = o.extension()?.to_str()?;
            extension.parse::<PictureFormat>().ok()
        });
    let format = match (args.format, named) {
        (Some(asked), Some(named)) if asked != named => {
            return Err(format!(
                "--format {} does not match the output's .{} extension",
                asked.extension(),
                named.extension()
            ));
        }
        (Some(asked), _) => asked,
        (None, Some(named)) => named,
        (None, None) => PictureFormat::Svg,
    };
    let output = match &args.output {
        Some(output) => output.clone(),
        None if is_dash(&args.input) => {
            return Err("standard input needs -o (a file, or - for standard output)".into());
        }
        None => beside(&args.input, format),
    };
    Ok((format, output))
}

fn beside(input: &Path, format: PictureFormat) -> PathBuf {
    let stem = input.file_stem().unwrap_or_default().to_string_lossy();
    input.with_file_name(format!("{stem}.uv.{}", format.extension()))
}

fn file_name(input: &Path) -> String {
    if is_dash(input) {
        return "standard input".into();
    }
    input.file_name().map_or_else(
        || input.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
