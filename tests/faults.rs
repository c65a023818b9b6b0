//! Faults a real process must survive: SIGTERM while it is busy. (Clients that vanish, slow
//! uploads and overload are in tests/http.rs, against a server in the test's own process.)

use std::time::{Duration, Instant};
use tspace_testkit::glb_builder::grid;
#[allow(unused_imports)]
use tspace_testkit::process::{ServerProcess, status_line};

/// The jobs gauges (queued, running) from /metrics.
fn jobs(server: &ServerProcess) -> Option<(u64, u64)> {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(&server.addr).ok()?;
    stream
        .write_all(b"GET /metrics HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n")
        .ok()?;
    let mut text = String::new();
    stream.read_to_string(&mut text).ok()?;
    let value = |name: &str| -> Option<u64> {
        text.lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.trim().parse().ok())
    };
    Some((
        value("tspace_jobs_queued ")?,
        value("tspace_jobs_running ")?,
    ))
}

/// POSTs `body` to /v1/tangents on a thread of its own, which returns the raw response.
fn post_in_background(addr: &str, body: Vec<u8>) -> std::thread::JoinHandle<Vec<u8>> {
    let addr = addr.to_owned();
    std::thread::spawn(move || {
        use std::io::{Read, Write};
        let mut stream = std::net::TcpStream::connect(&addr).unwrap();
        let head = format!(
            "POST /v1/tangents HTTP/1.1\r\nHost: t\r\nContent-Type: model/gltf-binary\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            body.len()
        );
        stream.write_all(head.as_bytes()).unwrap();
        stream.write_all(&body).unwrap();
        let mut response = Vec::new();
        stream.read_to_end(&mut response).unwrap();
        response
    })
}

/// Polls the jobs gauges until `ready(queued, running)`, for at most 20 s.
fn wait_for_jobs(server: &ServerProcess, what: &str, ready: impl Fn(u64, u64) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let (queued, running) = jobs(server).unwrap_or((0, 0));
        if ready(queued, running) {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "waited in vain for {what}: {queued} queued, {running} running"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// SIGTERM while one job runs and others wait: every accepted request still gets its whole
/// answer, new connections are refused, and the process exits 0.
#[cfg(unix)]
#[test]
fn sigterm_under_load_finishes_accepted_work_and_refuses_new() {
    let server = ServerProcess::start(
        env!("CARGO_BIN_EXE_tspace"),
        &["--concurrency", "1", "--queue", "8"],
    );
    // One large job first, and only once it runs four small ones: they queue behind it while it
    // runs, however fast the core is. (Five jobs of one size raced the uploads: as the core got
    // faster, the first could finish before the last had arrived.)
    let accepted = 5;
    let mut clients = vec![post_in_background(&server.addr, grid(700))];
    wait_for_jobs(&server, "the large job to run", |_, running| running == 1);
    clients.extend((1..accepted).map(|_| post_in_background(&server.addr, grid(100))));
    wait_for_jobs(
        &server,
        "one job running, the rest queued",
        |queued, running| running == 1 && queued + running == accepted,
    );
    server.terminate();
    // New connections are refused while the accepted work drains.
    std::thread::sleep(Duration::from_millis(50));
    let refused_at = Instant::now();
    let late = std::net::TcpStream::connect(&server.addr);
    assert!(late.is_err(), "a connection was accepted after SIGTERM");
    let mut finished = Vec::new();
    for client in clients {
        finished.push(client.join().unwrap());
    }
    let drained_for = refused_at.elapsed();
    for response in &finished {
        assert_eq!(status_line(response), "HTTP/1.1 200 OK");
        let scene = &response[response.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4..];
        let parsed = tspace::scene::gltf::glb::parse(scene).expect("a whole GLB");
        assert!(parsed.json.len() > 100);
    }
    let mut server = server;
    let status = server
        .wait(Duration::from_secs(20))
        .expect("the process exits after draining");
    assert!(status.success(), "{status:?}");
    let logs = server.logs().join("\n");
    assert!(logs.contains("shutting down"), "{logs}");
    eprintln!(
        "SIGTERM with {accepted} accepted requests: all answered 200 within {:.0} ms of the refusal; exit {status}",
        drained_for.as_secs_f64() * 1e3
    );
}

/// An answered problem leaves a log line with its code, inside the request's span (so with its
/// id): the response line beside it gives only the status, which several codes share.
#[test]
fn a_problem_is_logged_with_its_code_and_request_id() {
    let server = ServerProcess::start(env!("CARGO_BIN_EXE_tspace"), &[]);
    let response = server.post("/v1/tangents", b"glTX", "model/gltf-binary");
    assert!(
        status_line(&response).starts_with("HTTP/1.1 400"),
        "{}",
        status_line(&response)
    );
    let deadline = Instant::now() + Duration::from_secs(5);
    let line = loop {
        let found = server
            .logs()
            .into_iter()
            .find(|l| l.contains("code=malformed-glb"));
        match found {
            Some(line) => break line,
            None if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(20)),
            None => panic!("no problem line in {:#?}", server.logs()),
        }
    };
    assert!(
        line.contains("status=400") && line.contains("id="),
        "{line}"
    );
    server.terminate();
}
