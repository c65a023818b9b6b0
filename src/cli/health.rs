//! `tspace healthcheck`: a plain HTTP/1.1 GET with the standard library, so that a container
//! image needs no curl or wget for its `HEALTHCHECK`.

use super::Exit;
use clap::Args;
use std::io::{Read, Write};
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, TcpStream, ToSocketAddrs};
use std::time::Duration;

#[derive(Debug, Args)]
pub(crate) struct HealthArgs {
    /// The URL to GET (http:// only) [default: http://<addr>/healthz].
    #[arg(long)]
    url: Option<String>,
    /// The service's address; 0.0.0.0 and [::] mean this host.
    #[arg(long, env = "TSPACE_ADDR", default_value = "127.0.0.1:8080")]
    addr: String,
    /// Seconds to wait for connecting and for the answer, each.
    #[arg(long, default_value_t = 5)]
    timeout: u64,
}

/// Exit 0 when the service answers 2xx, else 1 with one line on stderr.
pub(crate) fn run(args: &HealthArgs) -> Exit {
    let url = args
        .url
        .clone()
        .unwrap_or_else(|| format!("http://{}/healthz", local(&args.addr)));
    match check(&url, Duration::from_secs(args.timeout.max(1))) {
        Ok(()) => Exit::Ok,
        Err(message) => {
            eprintln!("tspace: healthcheck {url}: {message}");
            Exit::Internal
        }
    }
}

/// An address a client can connect to: the unspecified address becomes loopback.
fn local(addr: &str) -> String {
    match addr.parse::<SocketAddr>() {
        Ok(mut a) => {
            if a.ip().is_unspecified() {
                a.set_ip(match a.ip() {
                    IpAddr::V4(_) => IpAddr::V4(Ipv4Addr::LOCALHOST),
                    IpAddr::V6(_) => IpAddr::V6(Ipv6Addr::LOCALHOST),
                });
            }
            a.to_string()
        }
        Err(_) => addr.to_owned(),
    }
}

fn check(url: &str, timeout: Duration) -> Result<(), String> {
    let rest = url
        .strip_prefix("http://")
        .ok_or("only http:// URLs are supported")?;
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/"),
    };
    if authority.is_empty() {
        return Err("the URL has no host".into());
    }
    let has_port = match authority.rsplit_once(':') {
        Some((host, _)) => !host.starts_with('[') || host.ends_with(']'),
        None => false,
    };
    let target = if has_port {
        authority.to_owned()
    } else {
        format!("{authority}:80")
    };
    let addrs: Vec<SocketAddr> = target
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve {target}: {e}"))?
        .collect();
    let mut last_error = format!("{target} resolves to no address");
    let mut stream = None;
    for addr in addrs {
        match TcpStream::connect_timeout(&addr, timeout) {
            Ok(s) => {
                stream = Some(s);
                break;
            }
            Err(e) => last_error = format!("cannot connect to {addr}: {e}"),
        }
    }
    let mut stream = stream.ok_or(last_error)?;
    let io = |e: std::io::Error| e.to_string();
    stream.set_read_timeout(Some(timeout)).map_err(io)?;
    stream.set_write_timeout(Some(timeout)).map_err(io)?;
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {authority}\r\nUser-Agent: tspace-healthcheck\r\nConnection: close\r\n\r\n"
    )
    .map_err(io)?;
    // The status line is all that is needed.
    let mut head = Vec::new();
    let mut buf = [0u8; 512];
    while !head.contains(&b'\n') && head.len() < 4096 {
        let n = stream.read(&mut buf).map_err(io)?;
        if n == 0 {
            break;
        }
        head.extend_from_slice(&buf[..n]);
    }
    let line = String::from_utf8_lossy(&head);
    let line = line.lines().next().unwrap_or("").trim();
    let mut parts = line.split_whitespace();
    match (parts.next(), parts.next()) {
        (Some(version), Some(status)) if version.starts_with("HTTP/") => {
            if status.len() == 3 && status.starts_with('2') {
                Ok(())
            } else {
                Err(format!("answered {line:?}"))
            }
        }
        _ => Err(format!("not an HTTP answer: {line:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unspecified_addresses_become_loopback() {
        assert_eq!(local("0.0.0.0:8080"), "127.0.0.1:8080");
        assert_eq!(local("[::]:8080"), "[::1]:8080");
        assert_eq!(local("10.0.0.1:80"), "10.0.0.1:80");
        assert_eq!(local("example:80"), "example:80");
    }
}
