//! The real `tspace serve` binary as a child process, for the tests and benches that need what
//! only a separate process shows: its own memory figures from /proc, signals, its exit status.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};

pub struct ServerProcess {
    child: Child,
    pub addr: String,
    logs: Arc<Mutex<Vec<String>>>,
}

impl ServerProcess {
    /// Starts `tspace serve --addr 127.0.0.1:0` with `args` and waits for its address line. Its
    /// log lines are collected on a thread, so that a full pipe never blocks the server.
    ///
    /// `binary` is the caller's `env!("CARGO_BIN_EXE_tspace")`: Cargo tells only the `tspace`
    /// package's own tests and benches where it built the binary.
    pub fn start(binary: &str, args: &[&str]) -> Self {
        let mut child = Command::new(binary)
            .args(["serve", "--addr", "127.0.0.1:0"])
            .args(args)
            .env("TSPACE_LOG", "info")
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the tspace binary starts");
        let mut lines = BufReader::new(child.stdout.take().expect("piped stdout")).lines();
        let addr = loop {
            let line = lines
                .next()
                .expect("the server logs its address")
                .expect("a log line");
            if let Some(rest) = line.split("addr=").nth(1) {
                break rest
                    .split_whitespace()
                    .next()
                    .unwrap_or_default()
                    .to_owned();
            }
        };
        let logs = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&logs);
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                sink.lock().unwrap().push(line);
            }
        });
        ServerProcess { child, addr, logs }
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The log lines written since the address line.
    pub fn logs(&self) -> Vec<String> {
        self.logs.lock().unwrap().clone()
    }

    /// A field of `/proc/<pid>/status` in bytes (`VmHWM` for the peak, `VmRSS` for now).
    pub fn memory(&self, field: &str) -> usize {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.pid()))
            .expect("/proc status of the server");
        let kb: usize = status
            .lines()
            .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .expect("the field in /proc status");
        kb * 1024
    }

    /// The page faults the process has taken that needed no disk read (`minflt` in
    /// `/proc/<pid>/stat`): nearly all of them fresh memory being touched for the first time.
    pub fn page_faults(&self) -> u64 {
        let stat = std::fs::read_to_string(format!("/proc/{}/stat", self.pid()))
            .expect("/proc stat of the server");
        // After the command name, which is in parentheses and may hold spaces, come the state
        // (field 3) and then the others in order: minflt is field 10.
        let rest = &stat[stat.rfind(')').expect("the command name's end") + 1..];
        rest.split_whitespace()
            .nth(7)
            .and_then(|v| v.parse().ok())
            .expect("minflt in /proc stat")
    }

    /// A blocking `POST` on a fresh connection; the whole answer, or what came of it when the
    /// connection failed.
    pub fn post(&self, path: &str, body: &[u8], content_type: &str) -> Vec<u8> {
        self.post_with(path, body, &[("Content-Type", content_type)])
    }

    /// [`ServerProcess::post`] with the given headers (`Content-Length` is added).
    pub fn post_with(&self, path: &str, body: &[u8], headers: &[(&str, &str)]) -> Vec<u8> {
        let Ok(mut stream) = std::net::TcpStream::connect(&self.addr) else {
            return Vec::new();
        };
        let headers: String = headers
            .iter()
            .map(|(name, value)| format!("{name}: {value}\r\n"))
            .collect();
        let head = format!(
            "POST {path} HTTP/1.1\r\nHost: t\r\n{headers}Content-Length: {}\r\nConnection: close\r\n\r\n",
            body.len()
        );
        let _ = stream.write_all(head.as_bytes());
        let _ = stream.write_all(body);
        let mut response = Vec::new();
        let _ = stream.read_to_end(&mut response);
        response
    }

    /// Sends SIGTERM.
    pub fn terminate(&self) {
        let status = Command::new("kill")
            .args(["-TERM", &self.pid().to_string()])
            .status()
            .expect("kill runs");
        assert!(status.success());
    }

    /// Waits for the process to exit, at most `limit`.
    pub fn wait(&mut self, limit: std::time::Duration) -> Option<ExitStatus> {
        let deadline = std::time::Instant::now() + limit;
        while std::time::Instant::now() < deadline {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Some(status);
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        None
    }
}

impl Drop for ServerProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The status line of an HTTP answer.
pub fn status_line(response: &[u8]) -> String {
    let end = response
        .windows(2)
        .position(|w| w == b"\r\n")
        .unwrap_or(response.len());
    String::from_utf8_lossy(&response[..end]).into_owned()
}
