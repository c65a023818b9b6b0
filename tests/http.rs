//! The HTTP service, started for real on an ephemeral loopback port and called with reqwest.

#[allow(unused_imports)]
use tspace_testkit::{fixture, glb_json};

use reqwest::multipart::{Form, Part};
use serde_json::{Value, json};
use std::time::Duration;
use tspace::config::ServerConfig;
use tspace::server::{Running, start};
use tspace_testkit::glb_builder::grid;

async fn server(config: ServerConfig) -> (Running, String) {
    let running = start(config).await.expect("server starts");
    let base = format!("http://{}", running.addr);
    (running, base)
}

/// `POST /v1/tangents` with `body` and no other header.
async fn post_tangents(base: &str, body: impl Into<reqwest::Body>) -> reqwest::Response {
    client()
        .post(format!("{base}/v1/tangents"))
        .body(body)
        .send()
        .await
        .unwrap()
}

/// A server that takes one upload at a time and gives up on a silent client after
/// `read_timeout`.
async fn one_upload_slot_server(read_timeout: Duration) -> (Running, String) {
    server(ServerConfig {
        in_flight: 1,
        read_timeout,
        ..ServerConfig::local()
    })
    .await
}

fn client() -> reqwest::Client {
    reqwest::Client::builder().build().unwrap()
}

/// The report summary a response carries in `X-Tspace-Report`.
fn summary_of(response: &reqwest::Response) -> Value {
    serde_json::from_str(response.headers()["x-tspace-report"].to_str().unwrap()).unwrap()
}

async fn problem(response: reqwest::Response, status: u16, code: &str) -> Value {
    assert_eq!(response.status().as_u16(), status);
    assert_eq!(
        response.headers()["content-type"].to_str().unwrap(),
        "application/problem+json"
    );
    let body: Value = response.json().await.unwrap();
    assert_eq!(body["code"], json!(code), "{body}");
    assert_eq!(body["type"], json!(format!("/problems/{code}")));
    assert_eq!(body["status"], json!(status));
    assert!(body["detail"].as_str().is_some_and(|d| !d.is_empty()));
    body
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_input_kind_gets_tangents() {
    let (running, base) = server(ServerConfig::local()).await;
    let http = client();

    // A raw GLB, sniffed.
    let response = http
        .post(format!("{base}/v1/tangents"))
        .body(grid(4))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "model/gltf-binary");
    let summary = summary_of(&response);
    assert_eq!(summary["generated"], json!(1));
    let bytes = response.bytes().await.unwrap();
    assert!(tspace::scene::gltf::glb::parse(&bytes).is_ok());

    // A .gltf with its buffer embedded, declared by media type; `all` because it has no normal map.
    let response = http
        .post(format!("{base}/v1/tangents?all=true"))
        .header("content-type", "model/gltf+json")
        .body(fixture("BoxTextured_embedded/BoxTextured.gltf"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let summary = summary_of(&response);
    assert_eq!(summary["generated"], json!(1));

    // A .gltf with its .bin as a part (names as curl -F sends them).
    let form = Form::new()
        .part(
            "file",
            Part::bytes(fixture("Avocado/Avocado.gltf")).file_name("Avocado.gltf"),
        )
        .part(
            "bin",
            Part::bytes(fixture("Avocado/Avocado.bin")).file_name("Avocado.bin"),
        );
    let response = http
        .post(format!("{base}/v1/tangents?overwrite=true"))
        .multipart(form)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let summary = summary_of(&response);
    assert_eq!(summary["generated"], json!(1));

    // OBJ with its MTL.
    let form = Form::new()
        .part(
            "file",
            Part::bytes(fixture("spider/spider.obj")).file_name("spider.obj"),
        )
        .part(
            "mtl",
            Part::bytes(fixture("spider/spider.mtl")).file_name("spider.mtl"),
        );
    let response = http
        .post(format!("{base}/v1/tangents?all=1&format=gltf"))
        .multipart(form)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "model/gltf+json");
    let gltf: Value = response.json().await.unwrap();
    assert!(
        gltf["buffers"][0]["uri"]
            .as_str()
            .unwrap()
            .starts_with("data:")
    );
    running.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn options_analyze_and_multipart_mixed() {
    let (running, base) = server(ServerConfig::local()).await;
    let http = client();
    let response = http
        .post(format!("{base}/v1/analyze?method=fast"))
        .header("content-type", "model/gltf-binary")
        .body(grid(4))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let report: Value = response.json().await.unwrap();
    assert_eq!(report["method"], json!("fast"));
    assert!(report.get("output_bytes").is_none());
    assert_eq!(report["primitives"][0]["action"], json!("generated"));

    let response = http
        .post(format!("{base}/v1/tangents"))
        .header("accept", "multipart/mixed")
        .body(grid(4))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let content_type = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    let boundary = content_type.split("boundary=").nth(1).unwrap().to_owned();
    let body = response.bytes().await.unwrap();
    let text = String::from_utf8_lossy(&body);
    let sections: Vec<&str> = text.split(&format!("--{boundary}")).collect();
    assert_eq!(sections.len(), 4, "preamble, report, scene, end");
    assert!(sections[1].contains("application/json"));
    let json_start = sections[1].find("\r\n\r\n").unwrap() + 4;
    let report: Value = serde_json::from_str(sections[1][json_start..].trim_end()).unwrap();
    assert_eq!(report["summary"]["generated"], json!(1));
    assert!(sections[2].contains("model/gltf-binary"));
    assert!(sections[2].contains("glTF"));

    // A debug scene says so in its report and in the name it is sent under.
    let response = http
        .post(format!("{base}/v1/tangents?debug=colors"))
        .header("accept", "multipart/mixed")
        .body(grid(4))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let content_type = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    let body = response.bytes().await.unwrap();
    let head = String::from_utf8_lossy(&body[..body.len().min(64 << 10)]).into_owned();
    assert!(head.contains("filename=\"scene.debug.glb\""), "{head}");
    let parts = mixed_parts(&content_type, body).await;
    let report: Value = serde_json::from_slice(&parts[0].1).unwrap();
    assert_eq!(report["debug_colors"]["primitives"], json!(1));
    assert!(
        report["findings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["code"] == "debug_colors" && f["severity"] == "warning")
    );
    let scene = glb_json(&parts[1].1);
    assert!(scene["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"].is_u64());

    for bad in ["method=magic", "debug=wireframe"] {
        let response = http
            .post(format!("{base}/v1/tangents?{bad}"))
            .body(grid(2))
            .send()
            .await
            .unwrap();
        problem(response, 400, "invalid-option").await;
    }
    running.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_error_is_a_problem() {
    let config = ServerConfig {
        body_limit: 100_000,
        ..ServerConfig::local()
    };
    let (running, base) = server(config).await;
    let http = client();
    let post = |body: Vec<u8>, content_type: &'static str| {
        http.post(format!("{base}/v1/tangents"))
            .header("content-type", content_type)
            .body(body)
            .send()
    };
    let mut bad_glb = fixture("Box/Box.glb");
    bad_glb.truncate(40);
    problem(
        post(bad_glb, "model/gltf-binary").await.unwrap(),
        400,
        "malformed-glb",
    )
    .await;
    problem(
        post(b"{\"asset\":".to_vec(), "model/gltf+json")
            .await
            .unwrap(),
        400,
        "malformed-json",
    )
    .await;
    problem(
        post(vec![1, 2, 3], "image/png").await.unwrap(),
        415,
        "unsupported-media-type",
    )
    .await;
    problem(
        post(Vec::new(), "model/gltf-binary").await.unwrap(),
        400,
        "missing-file",
    )
    .await;
    let body = problem(
        post(fixture("Avocado/Avocado.gltf"), "model/gltf+json")
            .await
            .unwrap(),
        422,
        "missing-resource",
    )
    .await;
    assert!(body["detail"].as_str().unwrap().contains("Avocado.bin"));
    problem(
        post(vec![b'v'; 150_000], "model/obj").await.unwrap(),
        413,
        "body-too-large",
    )
    .await;
    // Over the limit without a Content-Length: a chunked body is cut off at the limit.
    let status = chunked_post(running.addr, "/v1/tangents", 20, 10_000).await;
    assert!(status.starts_with("HTTP/1.1 413"), "{status}");
    let response = http.get(format!("{base}/nowhere")).send().await.unwrap();
    assert_eq!(response.status(), 404);
    assert_eq!(
        response.headers()["content-type"],
        "application/problem+json"
    );
    let response = http
        .get(format!("{base}/v1/tangents"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 405);
    assert_eq!(
        response.headers()["content-type"],
        "application/problem+json"
    );
    running.shutdown().await.unwrap();
}

/// Sends `count` chunks of `size` spaces with chunked transfer encoding; returns the status line.
async fn chunked_post(addr: std::net::SocketAddr, path: &str, count: usize, size: usize) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut stream = tokio::net::TcpStream::connect(addr).await.unwrap();
    let head = format!(
        "POST {path} HTTP/1.1\r\nHost: test\r\nContent-Type: model/obj\r\nTransfer-Encoding: chunked\r\nConnection: close\r\n\r\n"
    );
    stream.write_all(head.as_bytes()).await.unwrap();
    let chunk = vec![b' '; size];
    for _ in 0..count {
        // The server may answer and close before all chunks are sent.
        if stream
            .write_all(format!("{size:x}\r\n").as_bytes())
            .await
            .is_err()
            || stream.write_all(&chunk).await.is_err()
            || stream.write_all(b"\r\n").await.is_err()
        {
            break;
        }
    }
    let _ = stream.write_all(b"0\r\n\r\n").await;
    let mut response = Vec::new();
    let _ = stream.read_to_end(&mut response).await;
    String::from_utf8_lossy(&response)
        .lines()
        .next()
        .unwrap_or("")
        .to_owned()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_queue_sheds_load_and_recovers() {
    let config = ServerConfig {
        concurrency: 1,
        queue: 0,
        ..ServerConfig::local()
    };
    let (running, base) = server(config).await;
    let http = client();
    let heavy = grid(400);
    let requests = (0..4).map(|_| {
        http.post(format!("{base}/v1/tangents"))
            .body(heavy.clone())
            .send()
    });
    let responses = futures_join_all(requests).await;
    let statuses: Vec<u16> = responses
        .iter()
        .map(|r| r.as_ref().unwrap().status().as_u16())
        .collect();
    assert!(statuses.contains(&200), "{statuses:?}");
    assert!(statuses.contains(&503), "{statuses:?}");
    for response in responses.into_iter().flatten() {
        if response.status() == 503 {
            assert_eq!(response.headers()["retry-after"], "1");
            problem(response, 503, "overloaded").await;
        }
    }
    // Once the work is done, the server takes requests again.
    let response = http
        .post(format!("{base}/v1/tangents"))
        .body(grid(4))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);

    let metrics = metrics_text(&base).await;
    assert!(
        metrics.contains("tspace_rejections_total{reason=\"overloaded\"}"),
        "{metrics}"
    );
    assert!(metrics.contains("tspace_requests_total{route=\"/v1/tangents\",status=\"503\"}"));
    assert!(metrics.contains("tspace_requests_total{route=\"/v1/tangents\",status=\"200\"}"));
    assert!(
        metrics
            .contains("tspace_request_duration_seconds_bucket{route=\"/v1/tangents\",le=\"+Inf\"}")
    );
    let triangles: u64 = metrics
        .lines()
        .find_map(|l| l.strip_prefix("tspace_triangles_processed_total "))
        .unwrap()
        .parse()
        .unwrap();
    assert!(triangles >= 2 * 400 * 400, "{triangles}");
    assert!(metrics.contains("tspace_jobs_queued 0"));
    running.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploads_beyond_the_bound_are_refused_before_they_are_buffered() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let (running, base) = one_upload_slot_server(Duration::from_millis(800)).await;
    // A trickling client holds the one upload slot.
    let mut slow = tokio::net::TcpStream::connect(running.addr).await.unwrap();
    slow.write_all(b"POST /v1/tangents HTTP/1.1\r\nHost: t\r\nContent-Type: model/obj\r\nContent-Length: 1000\r\n\r\nv 0 0 0\n")
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    // A whole body sent at once: read and thrown away, so the client gets its 503, not a reset.
    let refused = post_tangents(&base, grid(100)).await;
    assert_eq!(refused.headers()["retry-after"], "1");
    problem(refused, 503, "overloaded").await;
    // A client waiting for 100 Continue is answered without being asked for its body.
    let mut polite = tokio::net::TcpStream::connect(running.addr).await.unwrap();
    polite
        .write_all(b"POST /v1/tangents HTTP/1.1\r\nHost: t\r\nContent-Type: model/obj\r\nContent-Length: 100000\r\nExpect: 100-continue\r\n\r\n")
        .await
        .unwrap();
    // The whole answer, then the close: a body announced and never sent ends the connection.
    let mut answer = Vec::new();
    tokio::time::timeout(Duration::from_secs(5), polite.read_to_end(&mut answer))
        .await
        .unwrap()
        .unwrap();
    let answer = String::from_utf8_lossy(&answer).to_lowercase();
    assert!(answer.starts_with("http/1.1 503"), "{answer}");
    assert!(answer.contains("\r\nconnection: close\r\n"), "{answer}");
    assert!(answer.ends_with("\"overloaded\"}"), "{answer}");
    // The slow client times out and frees the slot; uploads are taken again.
    let mut answer = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(5), slow.read_to_end(&mut answer)).await;
    assert!(String::from_utf8_lossy(&answer).starts_with("HTTP/1.1 408"));
    let response = post_tangents(&base, grid(4)).await;
    assert_eq!(response.status(), 200);
    running.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_stops_reading_is_cut_off_and_frees_its_slot() {
    use tokio::io::AsyncWriteExt;
    let (running, base) = one_upload_slot_server(Duration::from_millis(500)).await;
    // A tiny receive window, and nothing read: the server's writes of a 12 MB answer stall.
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let mut reader = socket.connect(running.addr).await.unwrap();
    let body = grid(400);
    reader
        .write_all(
            format!(
                "POST /v1/tangents HTTP/1.1\r\nHost: t\r\nContent-Type: model/gltf-binary\r\nContent-Length: {}\r\n\r\n",
                body.len()
            )
            .as_bytes(),
        )
        .await
        .unwrap();
    reader.write_all(&body).await.unwrap();
    // While the answer is stuck, the one in-flight slot is taken.
    let mut refused = false;
    for _ in 0..100 {
        let response = client()
            .post(format!("{base}/v1/analyze"))
            .body(grid(2))
            .send()
            .await
            .unwrap();
        if response.status() == 503 {
            refused = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(refused, "the stuck answer never held the slot");
    // After the stall limit the connection is dropped, and the slot with it.
    let mut answered = false;
    for _ in 0..100 {
        tokio::time::sleep(Duration::from_millis(50)).await;
        let response = client()
            .post(format!("{base}/v1/analyze"))
            .body(grid(2))
            .send()
            .await
            .unwrap();
        if response.status() == 200 {
            answered = true;
            break;
        }
    }
    assert!(answered, "the stuck reader kept its slot");
    drop(reader);
    running.shutdown().await.unwrap();
}

/// Awaits every future, in order (no extra dependency for `join_all`).
async fn futures_join_all<F>(futures: impl Iterator<Item = F>) -> Vec<F::Output>
where
    F: std::future::Future + Send + 'static,
    F::Output: Send + 'static,
{
    let handles: Vec<_> = futures.map(tokio::spawn).collect();
    let mut out = Vec::new();
    for handle in handles {
        out.push(handle.await.unwrap());
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slow_work_times_out_with_504() {
    let config = ServerConfig {
        timeout: Duration::from_millis(1),
        ..ServerConfig::local()
    };
    let (running, base) = server(config).await;
    let response = post_tangents(&base, grid(300)).await;
    let body = problem(response, 504, "timeout").await;
    assert_eq!(
        body["detail"],
        json!("the scene took longer than 0.001 s"),
        "the detail names the timeout as set"
    );
    running.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_trickled_upload_times_out_without_holding_a_worker() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let config = ServerConfig {
        read_timeout: Duration::from_millis(300),
        concurrency: 1,
        // The trickling upload holds a place in the pool (not the worker) until it times out.
        queue: 1,
        ..ServerConfig::local()
    };
    let (running, base) = server(config).await;
    let mut slow = tokio::net::TcpStream::connect(running.addr).await.unwrap();
    slow.write_all(b"POST /v1/tangents HTTP/1.1\r\nHost: t\r\nContent-Type: model/obj\r\nContent-Length: 1000\r\n\r\nv 0 0 0\n")
        .await
        .unwrap();
    // While it trickles, the single worker still serves others.
    let response = post_tangents(&base, grid(2)).await;
    assert_eq!(response.status(), 200);
    let mut answer = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(5), slow.read_to_end(&mut answer)).await;
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("/problems/request-timeout"));
    running.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_drains_an_in_flight_request() {
    let (running, base) = server(ServerConfig::local()).await;
    let body = grid(400);
    let request = tokio::spawn(async move {
        // The client (and its keep-alive connection) ends with this task.
        let response = post_tangents(&base, body).await;
        let status = response.status();
        (status, response.bytes().await.unwrap().len())
    });
    // Let the request arrive, then shut down while it is in flight.
    tokio::time::sleep(Duration::from_millis(100)).await;
    let addr = running.addr;
    let shutdown = tokio::spawn(running.shutdown());
    let (status, length) = request.await.unwrap();
    assert_eq!(status, 200);
    assert!(length > 0);
    shutdown.await.unwrap().unwrap();
    // The listener is gone.
    assert!(tokio::net::TcpStream::connect(addr).await.is_err());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_readiness_and_documentation() {
    let (running, base) = server(ServerConfig::local()).await;
    let http = client();
    assert_eq!(
        http.get(format!("{base}/healthz"))
            .send()
            .await
            .unwrap()
            .status(),
        200
    );
    assert_eq!(
        http.get(format!("{base}/readyz"))
            .send()
            .await
            .unwrap()
            .status(),
        200
    );
    let api: Value = http
        .get(format!("{base}/openapi.json"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    for route in ["/v1/tangents", "/v1/analyze"] {
        let body = &api["paths"][route]["post"]["requestBody"]["content"];
        for media in ["model/gltf-binary", "model/gltf+json", "model/obj"] {
            assert_eq!(body[media]["schema"]["format"], "binary", "{route} {media}");
        }
        assert!(body["multipart/form-data"].is_object(), "{route}");
    }
    let docs = http.get(format!("{base}/docs/")).send().await.unwrap();
    assert_eq!(docs.status(), 200);
    assert!(docs.text().await.unwrap().contains("swagger"));
    let about = http
        .get(format!("{base}/problems/draco-too-large"))
        .send()
        .await
        .unwrap();
    assert!(about.text().await.unwrap().contains("413"));
    let response = http.get(format!("{base}/healthz")).send().await.unwrap();
    assert!(response.headers().contains_key("x-request-id"));
    running.shutdown().await.unwrap();
}

/// The exposition text of /metrics.
async fn metrics_text(base: &str) -> String {
    client()
        .get(format!("{base}/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap()
}

/// The jobs gauges, read from /metrics.
async fn gauges(base: &str) -> (u64, u64) {
    let text = metrics_text(base).await;
    let value = |name: &str| -> u64 {
        text.lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.trim().parse().ok())
            .unwrap()
    };
    (value("tspace_jobs_queued "), value("tspace_jobs_running "))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clients_that_vanish_leave_nothing_behind() {
    use tokio::io::AsyncWriteExt;
    let (running, base) = server(ServerConfig::local()).await;
    let head = |length: usize| {
        format!(
            "POST /v1/tangents HTTP/1.1\r\nHost: t\r\nContent-Type: model/gltf-binary\r\nContent-Length: {length}\r\n\r\n"
        )
    };
    // Gone mid-upload: half the body, then the connection closes.
    let body = grid(300);
    let mut upload = tokio::net::TcpStream::connect(running.addr).await.unwrap();
    upload.write_all(head(body.len()).as_bytes()).await.unwrap();
    upload.write_all(&body[..body.len() / 2]).await.unwrap();
    drop(upload);
    // Gone mid-download: the answer has begun (status line and the first 64 KiB of a scene of
    // several MB), then the connection closes.
    let mut download = tokio::net::TcpStream::connect(running.addr).await.unwrap();
    download
        .write_all(head(body.len()).as_bytes())
        .await
        .unwrap();
    download.write_all(&body).await.unwrap();
    let mut first = vec![0u8; 64 << 10];
    tokio::io::AsyncReadExt::read_exact(&mut download, &mut first)
        .await
        .unwrap();
    assert!(first.starts_with(b"HTTP/1.1 200"));
    drop(download);
    // Gone before the answer: the whole body, then the connection closes.
    for _ in 0..3 {
        let mut download = tokio::net::TcpStream::connect(running.addr).await.unwrap();
        download
            .write_all(head(body.len()).as_bytes())
            .await
            .unwrap();
        download.write_all(&body).await.unwrap();
        drop(download);
    }
    // The abandoned jobs finish or are dropped; the gauges return to zero.
    let mut settled = false;
    for _ in 0..100 {
        if gauges(&base).await == (0, 0) {
            settled = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(settled, "jobs still counted: {:?}", gauges(&base).await);
    let response = post_tangents(&base, grid(4)).await;
    assert_eq!(response.status(), 200);
    running.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_problem_code_has_a_page() {
    use tspace::scene::error::ProblemCode;
    let (running, base) = server(ServerConfig::local()).await;
    let http = client();
    let page = |slug: String| http.get(format!("{base}/problems/{slug}")).send();
    for code in ProblemCode::ALL {
        let response = page(code.to_string()).await.unwrap();
        assert_eq!(response.status(), 200, "{code}");
        let expected = format!("{code} (HTTP {}): {}.\n", code.status(), code.title());
        assert_eq!(response.text().await.unwrap(), expected);
    }
    // The three that once had no page.
    for (slug, line) in [
        ("not-found", "not-found (HTTP 404): Not Found.\n"),
        (
            "method-not-allowed",
            "method-not-allowed (HTTP 405): Method Not Allowed.\n",
        ),
        (
            "output-too-large",
            "output-too-large (HTTP 413): The output would be over the format's size limit.\n",
        ),
    ] {
        let response = page(slug.to_owned()).await.unwrap();
        assert_eq!(response.status(), 200, "{slug}");
        assert_eq!(response.text().await.unwrap(), line);
    }
    let response = page("no-such-code".to_owned()).await.unwrap();
    assert_eq!(response.status(), 404);
    running.shutdown().await.unwrap();
}

/// The stem of the `multipart/mixed` boundary, as a delimiter line and a close delimiter.
const BOUNDARY_LINES: &[u8] =
    b"\r\n--tspace-report-and-scene-7c1f3a\r\n\r\n--tspace-report-and-scene-7c1f3a--\r\n";

/// A GLB whose BIN chunk holds [`BOUNDARY_LINES`] in a buffer view nothing uses: the scene still
/// processes, and its output carries those bytes.
fn glb_holding_the_boundary() -> Vec<u8> {
    use tspace::scene::gltf::glb;
    let source = grid(4);
    let parsed = glb::parse(&source).unwrap();
    let mut json: Value = serde_json::from_slice(parsed.json).unwrap();
    let mut bin = parsed.bin.unwrap().to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let offset = bin.len();
    bin.extend_from_slice(BOUNDARY_LINES);
    let view = json!({"buffer": 0, "byteOffset": offset, "byteLength": BOUNDARY_LINES.len()});
    json["bufferViews"].as_array_mut().unwrap().push(view);
    json["buffers"][0]["byteLength"] = json!(bin.len());
    glb::write(&serde_json::to_vec(&json).unwrap(), Some(&bin), &[]).unwrap()
}

/// The parts of a `multipart/mixed` answer as `(name, bytes)`, read by multer (through axum)
/// with the boundary the answer declares. multer reads only `multipart/form-data`, whose parts
/// are delimited the same way, so the body goes to it under that type.
async fn mixed_parts(content_type: &str, body: bytes::Bytes) -> Vec<(String, bytes::Bytes)> {
    use axum::extract::{FromRequest, Multipart};
    let boundary = content_type
        .strip_prefix("multipart/mixed; boundary=")
        .unwrap_or_else(|| panic!("{content_type}"));
    let request = axum::http::Request::builder()
        .header(
            "content-type",
            format!("multipart/form-data; boundary={boundary}"),
        )
        .body(axum::body::Body::from(body))
        .unwrap();
    let mut multipart = Multipart::from_request(request, &()).await.unwrap();
    let mut parts = Vec::new();
    while let Some(field) = multipart.next_field().await.unwrap() {
        let name = field.name().unwrap_or_default().to_owned();
        parts.push((name, field.bytes().await.unwrap()));
    }
    parts
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_holding_the_boundary_stays_one_part() {
    let (running, base) = server(ServerConfig::local()).await;
    let scene = glb_holding_the_boundary();
    let post = |accept: &'static str| {
        client()
            .post(format!("{base}/v1/tangents"))
            .header("content-type", "model/gltf-binary")
            .header("accept", accept)
            .body(scene.clone())
            .send()
    };
    let response = post("model/gltf-binary").await.unwrap();
    assert_eq!(response.status(), 200);
    let plain = response.bytes().await.unwrap();
    let holds = |bytes: &[u8]| {
        bytes
            .windows(BOUNDARY_LINES.len())
            .any(|w| w == BOUNDARY_LINES)
    };
    assert!(holds(&plain), "the unused view is written back");

    let response = post("multipart/mixed").await.unwrap();
    assert_eq!(response.status(), 200);
    let content_type = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    let parts = mixed_parts(&content_type, response.bytes().await.unwrap()).await;
    let names: Vec<&str> = parts.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names, ["report", "scene"]);
    let report: Value = serde_json::from_slice(&parts[0].1).unwrap();
    assert_eq!(report["summary"]["generated"], json!(1));
    assert!(parts[1].1 == plain, "the scene part is the whole scene");
    running.shutdown().await.unwrap();
}

/// Issue 17's messages: a multipart upload whose scene part is an image is told which part it
/// was, not to "send multipart"; a buffer part under the wrong name is named, and a name that
/// differs only in case is pointed out.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn upload_mistakes_are_named_in_the_message() {
    let (running, base) = server(ServerConfig::local()).await;
    let http = client();
    let png = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR".to_vec();
    let form = Form::new().part(
        "file",
        Part::bytes(png)
            .file_name("texture.png")
            .mime_str("image/png")
            .unwrap(),
    );
    let response = http
        .post(format!("{base}/v1/tangents"))
        .multipart(form)
        .send()
        .await
        .unwrap();
    let body = problem(response, 415, "unsupported-media-type").await;
    let detail = body["detail"].as_str().unwrap();
    assert!(
        detail.contains("the part \"file\" (\"texture.png\")") && detail.contains("image/png"),
        "{detail}"
    );
    assert!(!detail.contains("multipart/form-data"), "{detail}");

    for (wrong, hint) in [
        ("avocado.bin", Some("\"avocado.bin\" differs only in case")),
        ("Avocado_v2.bin", None),
    ] {
        let form = Form::new()
            .part(
                "file",
                Part::bytes(fixture("Avocado/Avocado.gltf")).file_name("Avocado.gltf"),
            )
            .part(
                "bin",
                Part::bytes(fixture("Avocado/Avocado.bin")).file_name(wrong),
            );
        let response = http
            .post(format!("{base}/v1/tangents"))
            .multipart(form)
            .send()
            .await
            .unwrap();
        let body = problem(response, 422, "missing-resource").await;
        let detail = body["detail"].as_str().unwrap();
        assert!(
            detail.contains("\"Avocado.bin\"") && detail.contains(&format!("named \"{wrong}\"")),
            "{detail}"
        );
        assert_eq!(
            hint.is_some_and(|h| detail.contains(h)),
            hint.is_some(),
            "{detail}"
        );
    }
    running.shutdown().await.unwrap();
}

/// `normals=` and `normals_angle=` reach an OBJ's conversion, and the report says which
/// normals were made; an angle out of range is refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_normals_option_chooses_an_objs_generated_normals() {
    const CUBE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n\
                        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 3/2 4/3 2/4\nf 5/1 6/2 8/3 7/4\n\
                        f 1/1 2/2 6/3 5/4\nf 3/1 7/2 8/3 4/4\nf 1/1 5/2 7/3 3/4\nf 2/1 4/2 8/3 6/4\n";
    let (running, base) = server(ServerConfig::local()).await;
    let analyze = |query: &'static str| {
        client()
            .post(format!("{base}/v1/analyze{query}"))
            .header("content-type", "model/obj")
            .body(CUBE)
            .send()
    };
    let warning = |report: &Value| report["warnings"][0].as_str().unwrap_or("").to_owned();
    let report: Value = analyze("").await.unwrap().json().await.unwrap();
    assert!(
        warning(&report).starts_with(
            "normals generated for 12 triangles without vn: smooth, with edges sharper than 60° kept hard"
        ),
        "{report}"
    );
    let report: Value = analyze("?normals=flat")
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(
        warning(&report),
        "normals generated for 12 triangles without vn: flat (faceted), as normals=flat asks"
    );
    let report: Value = analyze("?normals=smooth&normals_angle=95.5")
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(warning(&report).contains("sharper than 95.5°"), "{report}");
    let body = problem(
        analyze("?normals_angle=200").await.unwrap(),
        400,
        "invalid-option",
    )
    .await;
    assert!(
        body["detail"].as_str().unwrap().contains("from 0 to 180"),
        "{body}"
    );
    running.shutdown().await.unwrap();
}

/// Asserts that a GET of each of `paths` is answered 200.
async fn answered(base: &str, paths: &[&str]) {
    for path in paths {
        let response = client().get(format!("{base}{path}")).send().await.unwrap();
        assert_eq!(response.status(), 200, "{path}");
    }
}

/// A key file holding `keys`, in a folder of the test's own: the folder and the file.
fn key_file(test: &str, keys: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("tspace-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("keys");
    std::fs::write(&file, keys).unwrap();
    (dir, file)
}

/// While the service is saturated, scene requests are refused at the door: a 503 problem with
/// `Retry-After`, counted in the metrics per route, while the probes, metrics and documents
/// stay answered. A request without a valid key still learns only that it needs one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_saturated_service_refuses_scenes_after_the_key_and_answers_probes() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let (dir, file) = key_file("shed", "key-for-ci\n");
    let (running, base) = server(ServerConfig {
        in_flight: 1,
        read_timeout: Duration::from_millis(800),
        api_keys_file: Some(file),
        ..ServerConfig::local()
    })
    .await;
    // A trickling client with a key holds the one in-flight slot.
    let mut slow = tokio::net::TcpStream::connect(running.addr).await.unwrap();
    slow.write_all(b"POST /v1/tangents HTTP/1.1\r\nHost: t\r\nAuthorization: Bearer key-for-ci\r\nContent-Type: model/obj\r\nContent-Length: 1000\r\n\r\nv 0 0 0\n")
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    let http = client();
    let post = |route: &str, key: Option<&str>| {
        let mut request = http
            .post(format!("{base}{route}"))
            .body(fixture("Box/Box.glb"));
        if let Some(key) = key {
            request = request.header("authorization", format!("Bearer {key}"));
        }
        request.send()
    };
    for key in [None, Some("wrong")] {
        let response = post("/v1/tangents", key).await.unwrap();
        problem(response, 401, "unauthorized").await;
    }
    for route in ["/v1/tangents", "/v1/analyze", "/v1/uv-layout"] {
        let response = post(route, Some("key-for-ci")).await.unwrap();
        assert_eq!(response.headers()["retry-after"], "1", "{route}");
        problem(response, 503, "overloaded").await;
    }
    answered(
        &base,
        &[
            "/healthz",
            "/metrics",
            "/openapi.json",
            "/problems/overloaded",
        ],
    )
    .await;
    let metrics = metrics_text(&base).await;
    for counted in [
        "tspace_rejections_total{reason=\"overloaded\"} 3",
        "tspace_rejections_total{reason=\"unauthorized\"} 2",
        "tspace_requests_total{route=\"/v1/analyze\",status=\"503\"} 1",
        "tspace_requests_total{route=\"/v1/uv-layout\",status=\"503\"} 1",
        "tspace_requests_total{route=\"/v1/tangents\",status=\"503\"} 1",
    ] {
        assert!(metrics.contains(counted), "{counted} in {metrics}");
    }
    // Once the slow client has timed out, its slot is free and scenes are taken again.
    let mut answer = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(5), slow.read_to_end(&mut answer)).await;
    assert!(String::from_utf8_lossy(&answer).starts_with("HTTP/1.1 408"));
    let response = post("/v1/tangents", Some("key-for-ci")).await.unwrap();
    assert_eq!(response.status(), 200);
    running.shutdown().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// With a key file, the scene routes need `Authorization: Bearer <key>`; a missing or wrong
/// key is a 401 problem with `WWW-Authenticate`, whose text never repeats the key sent; the
/// probes, metrics and the API's description stay open.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn api_keys_guard_the_scene_routes_only() {
    let (dir, file) = key_file("keys", "# pipeline\nkey-for-ci\n\nkey-for-artists\n");
    let (running, base) = server(ServerConfig {
        api_keys_file: Some(file.clone()),
        ..ServerConfig::local()
    })
    .await;
    let http = client();
    let post = |key: Option<&str>| {
        let mut request = http
            .post(format!("{base}/v1/tangents?all=true&method=axis"))
            .header("content-type", "model/gltf-binary")
            .body(fixture("Box/Box.glb"));
        if let Some(key) = key {
            request = request.header("authorization", key.to_owned());
        }
        request.send()
    };
    for (key, says) in [
        (None, "requires an API key"),
        (Some("Bearer wrong-guess"), "does not carry a valid API key"),
        (Some("Basic key-for-ci"), "does not carry a valid API key"),
    ] {
        let response = post(key).await.unwrap();
        assert_eq!(
            response.headers()["www-authenticate"],
            "Bearer realm=\"tspace\""
        );
        let body = problem(response, 401, "unauthorized").await;
        let detail = body["detail"].as_str().unwrap();
        assert!(detail.contains(says), "{detail}");
        assert!(
            !detail.contains("wrong-guess") && !detail.contains("key-for"),
            "{detail}"
        );
    }
    for key in ["Bearer key-for-ci", "bearer key-for-artists"] {
        let response = post(Some(key)).await.unwrap();
        assert_eq!(response.status(), 200, "{key}");
    }
    let analyze = http
        .post(format!("{base}/v1/analyze"))
        .body(fixture("Box/Box.glb"))
        .send()
        .await
        .unwrap();
    assert_eq!(analyze.status(), 401);
    let picture = http
        .post(format!("{base}/v1/uv-layout"))
        .body(fixture("Box/Box.glb"))
        .send()
        .await
        .unwrap();
    assert_eq!(picture.status(), 401);
    let metrics = metrics_text(&base).await;
    assert!(
        metrics.contains("tspace_rejections_total{reason=\"unauthorized\"} 5"),
        "{metrics}"
    );
    answered(
        &base,
        &[
            "/healthz",
            "/readyz",
            "/metrics",
            "/openapi.json",
            "/problems/unauthorized",
            "/",
            "/page/page.js",
        ],
    )
    .await;
    running.shutdown().await.unwrap();

    // A key file without a key, or missing, stops the service from starting, naming the file.
    std::fs::write(&file, "# nobody yet\n").unwrap();
    for config in [
        ServerConfig {
            api_keys_file: Some(file.clone()),
            ..ServerConfig::local()
        },
        ServerConfig {
            api_keys_file: Some(dir.join("absent")),
            ..ServerConfig::local()
        },
    ] {
        let Err(error) = start(config).await else {
            panic!("started without keys");
        };
        assert!(error.to_string().contains("the API key file"), "{error}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::MultiGzDecoder::new(bytes), &mut out).unwrap();
    out
}

/// A body sent gzip- or zstd-encoded is read as the scene it encodes (whole bodies and multipart
/// alike); an encoding tspace does not decode is a 415 naming the ones it does; a stream that
/// does not decode is a 400.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn compressed_request_bodies_are_decoded() {
    let (running, base) = server(ServerConfig::local()).await;
    let scene = grid(24);
    let plain = post_tangents(&base, scene.clone()).await;
    assert_eq!(plain.status(), 200);
    let expected = plain.bytes().await.unwrap();
    let send = |coding: &'static str, body: Vec<u8>| {
        client()
            .post(format!("{base}/v1/tangents"))
            .header("content-type", "model/gltf-binary")
            .header("content-encoding", coding)
            .body(body)
            .send()
    };

    for (coding, body) in [
        ("gzip", gzip(&scene)),
        ("x-gzip", gzip(&scene)),
        ("zstd", zstd::encode_all(&scene[..], 3).unwrap()),
        // Two gzip members, as `cat a.gz b.gz` makes.
        ("gzip", [gzip(&scene[..100]), gzip(&scene[100..])].concat()),
    ] {
        let response = send(coding, body).await.unwrap();
        assert_eq!(response.status(), 200, "{coding}");
        assert_eq!(response.bytes().await.unwrap(), expected, "{coding}");
    }

    let gltf = fixture("Avocado/Avocado.gltf");
    let bin = fixture("Avocado/Avocado.bin");
    let boundary = "tspace-test-boundary";
    let mut multipart_bytes = Vec::new();
    for (name, file_name, bytes) in [("file", "Avocado.gltf", gltf), ("bin", "Avocado.bin", bin)] {
        multipart_bytes.extend_from_slice(
            format!(
                "--{boundary}\r\nContent-Disposition: form-data; name=\"{name}\"; filename=\"{file_name}\"\r\n\r\n"
            )
            .as_bytes(),
        );
        multipart_bytes.extend_from_slice(&bytes);
        multipart_bytes.extend_from_slice(b"\r\n");
    }
    multipart_bytes.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    let response = client()
        .post(format!("{base}/v1/analyze"))
        .header(
            "content-type",
            format!("multipart/form-data; boundary={boundary}"),
        )
        .header("content-encoding", "zstd")
        .body(zstd::encode_all(&multipart_bytes[..], 3).unwrap())
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let report: Value = response.json().await.unwrap();
    assert_eq!(report["summary"]["primitives"], json!(1), "{report}");

    let refused = send("br", gzip(&scene)).await.unwrap();
    assert_eq!(refused.headers()["accept-encoding"], "gzip, zstd");
    let body = problem(refused, 415, "unsupported-encoding").await;
    assert!(body["detail"].as_str().unwrap().contains("br"), "{body}");
    problem(
        send("gzip, zstd", gzip(&scene)).await.unwrap(),
        415,
        "unsupported-encoding",
    )
    .await;

    let compressed = gzip(&scene);
    for (what, body) in [
        ("not gzip", scene.clone()),
        ("cut short", compressed[..compressed.len() / 2].to_vec()),
    ] {
        let response = send("gzip", body).await.unwrap();
        let body = problem(response, 400, "malformed-encoding").await;
        assert!(
            body["detail"].as_str().unwrap().contains("gzip"),
            "{what}: {body}"
        );
    }
    running.shutdown().await.unwrap();
}

/// Answers are compressed when the client asks for gzip or zstd, and decode to the very bytes
/// an uncompressed answer carries; the report header stays readable.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn answers_are_compressed_when_asked() {
    let (running, base) = server(ServerConfig::local()).await;
    let scene = grid(24);
    let ask = |accept: &'static str| {
        client()
            .post(format!("{base}/v1/tangents"))
            .header("accept-encoding", accept)
            .body(scene.clone())
            .send()
    };
    let plain = ask("identity").await.unwrap();
    assert!(plain.headers().get("content-encoding").is_none());
    let expected = plain.bytes().await.unwrap();

    let gzipped = ask("gzip").await.unwrap();
    assert_eq!(gzipped.headers()["content-encoding"], "gzip");
    assert!(gzipped.headers().contains_key("x-tspace-report"));
    let body = gzipped.bytes().await.unwrap();
    assert!(body.len() < expected.len());
    assert_eq!(gunzip(&body), expected);

    let zstded = ask("zstd, gzip;q=0.5").await.unwrap();
    assert_eq!(zstded.headers()["content-encoding"], "zstd");
    let body = zstded.bytes().await.unwrap();
    assert_eq!(zstd::decode_all(&body[..]).unwrap(), expected);

    // Problems too, as curl --compressed would receive them.
    let problem_answer = client()
        .post(format!("{base}/v1/tangents"))
        .header("accept-encoding", "gzip")
        .body(b"not a scene".to_vec())
        .send()
        .await
        .unwrap();
    assert_eq!(problem_answer.status(), 415);
    let body = problem_answer.bytes().await.unwrap();
    let problem: Value = serde_json::from_slice(&gunzip(&body)).unwrap();
    assert_eq!(problem["code"], json!("unsupported-media-type"));
    running.shutdown().await.unwrap();
}

/// `tspace_jobs_cancelled_total` from /metrics.
async fn jobs_cancelled(base: &str) -> u64 {
    let text = client()
        .get(format!("{base}/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    text.lines()
        .find_map(|l| l.strip_prefix("tspace_jobs_cancelled_total "))
        .and_then(|v| v.trim().parse().ok())
        .expect("the cancelled-jobs counter")
}

/// Waits until the pool runs and queues nothing; how long that took.
async fn until_the_pool_is_idle(running: &Running) -> Duration {
    let started = std::time::Instant::now();
    while running.app.pool.running() + running.app.pool.queued() > 0 {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "the worker stayed busy"
        );
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
    started.elapsed()
}

/// A scene whose request timed out (504), or whose client went away, stops its work: the
/// job ends cancelled (the counter says so; a job that ran to the end would not count) and
/// the one worker is free for the next request. The large scene takes hundreds of
/// milliseconds on one worker, and both endings are made certain rather than raced: the
/// server's timeout is far shorter than that (it counts from the job's start, not the
/// upload), and the impatient client leaves once its job is seen running. The time from the
/// 504 to a free worker is printed (the closing figures come from this).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_timed_out_or_abandoned_scene_frees_its_worker() {
    let one_worker = |timeout| ServerConfig {
        concurrency: 1,
        queue: 1,
        body_limit: 256 << 20,
        timeout,
        ..ServerConfig::local()
    };
    let large = grid(1400);
    let small = grid(8);

    let (running, base) = server(one_worker(Duration::from_millis(20))).await;
    let started = std::time::Instant::now();
    let timed_out = post_tangents(&base, large.clone()).await;
    let answered = started.elapsed();
    problem(timed_out, 504, "timeout").await;
    let freed = until_the_pool_is_idle(&running).await;
    assert_eq!(jobs_cancelled(&base).await, 1);
    assert_eq!(post_tangents(&base, small.clone()).await.status(), 200);
    eprintln!(
        "504 after {} ms; the worker was free {} ms later",
        answered.as_millis(),
        freed.as_millis()
    );
    running.shutdown().await.unwrap();

    // A client that gives up while its scene is being processed: its connection closes, the
    // handler is dropped, and the work stops with it.
    let (running, base) = server(one_worker(Duration::from_secs(60))).await;
    let impatient = tokio::spawn({
        let request = client().post(format!("{base}/v1/tangents")).body(large);
        async move { request.send().await }
    });
    let waiting = std::time::Instant::now();
    while running.app.pool.running() == 0 {
        assert!(!impatient.is_finished(), "the large scene was answered");
        assert!(
            waiting.elapsed() < Duration::from_secs(60),
            "the large scene never started"
        );
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    impatient.abort();
    let gone = std::time::Instant::now();
    let freed = until_the_pool_is_idle(&running).await;
    assert_eq!(jobs_cancelled(&base).await, 1);
    assert_eq!(post_tangents(&base, small).await.status(), 200);
    eprintln!(
        "the client left; the worker was free {} ms later",
        (gone.elapsed().max(freed)).as_millis()
    );
    running.shutdown().await.unwrap();
}

/// `/v1/uv-layout`: the picture of NormalTangentMirrorTest (a .gltf and its .bin as parts),
/// whose legend gives the counts `/v1/analyze` gives; PNG on request; one primitive chosen;
/// problems for what cannot be drawn.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uv_layout_pictures_agree_with_the_report() {
    let (running, base) = server(ServerConfig::local()).await;
    let http = client();
    let form = || {
        Form::new()
            .part(
                "file",
                Part::bytes(fixture(
                    "NormalTangentMirrorTest/NormalTangentMirrorTest.gltf",
                ))
                .file_name("NormalTangentMirrorTest.gltf"),
            )
            .part(
                "bin",
                Part::bytes(fixture(
                    "NormalTangentMirrorTest/NormalTangentMirrorTest.bin",
                ))
                .file_name("NormalTangentMirrorTest.bin"),
            )
    };
    let post = |path: String| http.post(format!("{base}{path}")).multipart(form()).send();
    let report: Value = post("/v1/analyze?overwrite=true".into())
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let diagnostics = &report["primitives"][0]["diagnostics"];
    let triangles = diagnostics["triangles"].as_u64().unwrap();
    let mirrored = diagnostics["mirrored_uv_triangles"]["count"]
        .as_u64()
        .unwrap();
    assert!(
        mirrored > 0,
        "the fixture mirrors half its UVs: {diagnostics}"
    );

    let response = post("/v1/uv-layout?overwrite=true".into()).await.unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "image/svg+xml");
    let svg = response.text().await.unwrap();
    assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
    assert!(
        svg.contains("NormalTangentMirrorTest.gltf"),
        "the title names the file"
    );
    assert!(svg.contains(&format!("mirrored UVs: {mirrored} triangles")));
    let ordinary = triangles - mirrored;
    let with_comma = |n: u64| format!("{},{:03}", n / 1000, n % 1000);
    assert!(svg.contains(&format!(
        "ordinary: {} of {} triangles",
        with_comma(ordinary),
        with_comma(triangles)
    )));

    let response = post("/v1/uv-layout?overwrite=true&format=png".into())
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "image/png");
    let png = response.bytes().await.unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    // The width in the IHDR chunk: the panel and its margins.
    assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), 1072);

    let chosen = post("/v1/uv-layout?overwrite=true&mesh=0&primitive=0".into())
        .await
        .unwrap();
    assert_eq!(chosen.status(), 200);
    let absent = post("/v1/uv-layout?overwrite=true&mesh=7".into())
        .await
        .unwrap();
    let body = problem(absent, 422, "nothing-to-draw").await;
    assert!(
        body["detail"]
            .as_str()
            .unwrap()
            .contains("meshes[0].primitives[0]")
    );
    let bad = post("/v1/uv-layout?format=gif".into()).await.unwrap();
    problem(bad, 400, "invalid-option").await;
    let orphan = post("/v1/uv-layout?primitive=0".into()).await.unwrap();
    problem(orphan, 400, "invalid-option").await;
    // A scene with nothing that needs tangents: Box has no normal map.
    let response = http
        .post(format!("{base}/v1/uv-layout"))
        .header("content-type", "model/gltf-binary")
        .body(fixture("Box/Box.glb"))
        .send()
        .await
        .unwrap();
    problem(response, 422, "nothing-to-draw").await;
    running.shutdown().await.unwrap();
}

/// The page and its files are served with a policy that lets in nothing but themselves (and the
/// `blob:` pictures they make), and stay open on a server that requires keys.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_page_is_served_with_its_own_files_only() {
    let (running, base) = server(ServerConfig::local()).await;
    let http = client();
    for (path, media_type, needle) in [
        (
            "/",
            "text/html; charset=utf-8",
            "<script type=\"module\" src=\"/page/page.js\">",
        ),
        (
            "/page/page.js",
            "text/javascript; charset=utf-8",
            "/v1/uv-layout",
        ),
        ("/page/page.css", "text/css; charset=utf-8", "#uv-layout"),
    ] {
        let response = http.get(format!("{base}{path}")).send().await.unwrap();
        assert_eq!(response.status(), 200, "{path}");
        let headers = response.headers();
        assert_eq!(headers["content-type"], media_type, "{path}");
        let policy = headers["content-security-policy"].to_str().unwrap();
        assert!(policy.contains("default-src 'none'"), "{policy}");
        assert!(policy.contains("script-src 'self'"), "{policy}");
        assert_eq!(headers["x-content-type-options"], "nosniff");
        assert!(response.text().await.unwrap().contains(needle), "{path}");
    }
    running.shutdown().await.unwrap();
}

/// An answer given before the upload is read (an option the route does not take, a missing
/// key) reaches a client still sending a body larger than the socket buffers, and the
/// connection stays usable: closing it with the body unread would reset it under the answer.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_answer_before_the_upload_reaches_a_client_still_sending_it() {
    let (dir, file) = key_file("unread", "key-for-ci\n");
    let body = vec![b'#'; 24 * 1024 * 1024];
    let (open, open_base) = server(ServerConfig::local()).await;
    let (locked, locked_base) = server(ServerConfig {
        api_keys_file: Some(file),
        ..ServerConfig::local()
    })
    .await;
    let http = client();
    for round in 0..2 {
        for (base, route, status, code) in [
            (&open_base, "/v1/tangents?bogus=1", 400, "invalid-option"),
            (&open_base, "/v1/analyze?method=none", 400, "invalid-option"),
            (
                &open_base,
                "/v1/uv-layout?format=gif",
                400,
                "invalid-option",
            ),
            (&locked_base, "/v1/tangents", 401, "unauthorized"),
        ] {
            let response = http
                .post(format!("{base}{route}"))
                .body(body.clone())
                .send()
                .await
                .unwrap_or_else(|e| panic!("{route}, round {round}: {e:?}"));
            problem(response, status, code).await;
        }
    }
    // A chunked upload declares no length; it is drained up to the body limit all the same.
    {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let mut stream = tokio::net::TcpStream::connect(open.addr).await.unwrap();
        stream
            .write_all(b"POST /v1/tangents?bogus=1 HTTP/1.1\r\nHost: t\r\nTransfer-Encoding: chunked\r\n\r\n")
            .await
            .unwrap();
        let chunk = vec![b'#'; 1024 * 1024];
        for _ in 0..24 {
            stream.write_all(b"100000\r\n").await.unwrap();
            stream.write_all(&chunk).await.unwrap();
            stream.write_all(b"\r\n").await.unwrap();
        }
        stream.write_all(b"0\r\n\r\n").await.unwrap();
        let mut head = [0u8; 12];
        stream.read_exact(&mut head).await.unwrap();
        assert_eq!(&head, b"HTTP/1.1 400");
    }
    open.shutdown().await.unwrap();
    locked.shutdown().await.unwrap();
    drop(dir);
}
