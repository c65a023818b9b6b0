//! The compressed fixtures end to end through the real binary: over HTTP (`tspace serve`) and on
//! the command line (`tspace process`), one of each kind (Draco, KHR_mesh_quantization, and
//! gltfpack's `-cc` meshopt), with `overwrite` and `all`. Both give the same bytes, and those are
//! validator-clean, in the expected storage, with tangents that agree with bevy_mikktspace run on
//! the written (decoded) geometry within what the storage allows.

use std::process::Command;
use tspace_testkit::fixtures::{assert_valid_output, glb_json, workspace_root};
use tspace_testkit::process::{ServerProcess, status_line};
use tspace_testkit::written::{read_primitives, worst_angle_to_reference};

/// (fixture, the extension the output must use or `None`, the largest angle to the reference).
const CASES: [(&str, Option<&str>, f64); 3] = [
    // Written out of Draco as float: the reference's own tangents.
    ("WaterBottle_draco.glb", None, 0.01),
    // Byte tangents beside byte normals: rounding only (asin(√3/2 / 127) = 0.39°).
    ("WaterBottle_gltfpack_quantized.glb", None, 0.4),
    // Compressed again; octahedral byte tangents beside octahedral normals (0.73° grid).
    (
        "WaterBottle_gltfpack_cc.glb",
        Some("EXT_meshopt_compression"),
        0.75,
    ),
];

/// The body of an HTTP response with a Content-Length (what the service sends for a scene).
fn body(response: &[u8]) -> &[u8] {
    let at = response
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a header");
    &response[at + 4..]
}

#[test]
fn compressed_fixtures_round_trip_over_http_and_the_command_line() {
    let binary = env!("CARGO_BIN_EXE_tspace");
    let server = ServerProcess::start(binary, &[]);
    let dir = std::env::temp_dir().join(format!("tspace-compressed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, extension, bound) in CASES {
        let path = workspace_root().join("fixtures/compressed").join(name);
        let input = std::fs::read(&path).unwrap();

        let response = server.post(
            "/v1/tangents?overwrite=true&all=true",
            &input,
            "model/gltf-binary",
        );
        assert!(
            status_line(&response).starts_with("HTTP/1.1 200"),
            "{name}: {}",
            status_line(&response)
        );
        let over_http = body(&response).to_vec();

        let output = dir.join(name);
        let cli = Command::new(binary)
            .args(["process", "--overwrite", "--all"])
            .arg(&path)
            .arg("-o")
            .arg(&output)
            .output()
            .unwrap();
        assert!(cli.status.success(), "{name}: {cli:?}");
        let on_the_command_line = std::fs::read(&output).unwrap();
        assert!(
            over_http == on_the_command_line,
            "{name}: HTTP and the CLI differ"
        );

        assert_valid_output(name, &over_http);
        let json = glb_json(&over_http);
        let required = json["extensionsRequired"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        assert!(
            !required.iter().any(|e| e == "KHR_draco_mesh_compression"),
            "{name}"
        );
        if let Some(extension) = extension {
            assert!(
                required.iter().any(|e| e == extension),
                "{name}: {required:?}"
            );
        }
        for p in read_primitives(&over_http) {
            let worst = worst_angle_to_reference(&p);
            assert!(worst <= bound, "{name}: {worst}° from the reference");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
