//! A minimal HTTP/1.1 client that uploads the way curl does: a body over 1 MiB is announced
//! with `Expect: 100-continue` and sent only after the server's `100 Continue`, so that a
//! refusal costs the client a round trip instead of the upload. hyper's client (reqwest) has no
//! such mode: it sends every body whether or not the server wants it.
//!
//! Only what the load bench needs: POST of a fixed body, answers framed by `Content-Length` or
//! chunked, connections kept alive between accepted requests and dropped after a refusal (the
//! body that was announced and not sent leaves the connection's framing to the server's word).

use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;

/// How long curl waits for `100 Continue` before sending the body anyway (its default).
const EXPECT_WAIT: Duration = Duration::from_secs(1);

type Connection = BufReader<TcpStream>;

#[derive(Clone)]
pub struct Client {
    addr: std::net::SocketAddr,
    idle: Arc<Mutex<Vec<Connection>>>,
}

/// What came back: the final status, or the error that ended the exchange.
pub enum Outcome {
    Status(u16),
    Failed(String),
}

struct Head {
    status: u16,
    content_length: Option<usize>,
    chunked: bool,
    closes: bool,
}

impl Client {
    pub fn new(addr: std::net::SocketAddr) -> Self {
        Client {
            addr,
            idle: Arc::default(),
        }
    }

    /// POSTs `body` to `path` as `model/gltf-binary`.
    pub async fn post(&self, path: &str, body: &[u8]) -> Outcome {
        let reused = self.idle.lock().ok().and_then(|mut idle| idle.pop());
        let connection = match reused {
            Some(c) => c,
            None => match TcpStream::connect(self.addr).await {
                Ok(stream) => {
                    let _ = stream.set_nodelay(true);
                    BufReader::with_capacity(64 * 1024, stream)
                }
                Err(e) => return Outcome::Failed(format!("connecting: {e}")),
            },
        };
        match self.exchange(connection, path, body).await {
            Ok(status) => Outcome::Status(status),
            Err(e) => Outcome::Failed(e.to_string()),
        }
    }

    async fn exchange(
        &self,
        mut connection: Connection,
        path: &str,
        body: &[u8],
    ) -> std::io::Result<u16> {
        let expect = body.len() > 1 << 20;
        let head = format!(
            "POST {path} HTTP/1.1\r\nHost: {}\r\nContent-Type: model/gltf-binary\r\n\
             Content-Length: {}\r\n{}\r\n",
            self.addr,
            body.len(),
            if expect {
                "Expect: 100-continue\r\n"
            } else {
                ""
            }
        );
        connection.get_mut().write_all(head.as_bytes()).await?;
        if expect {
            // No word in time: the body is sent anyway, as curl does. A final answer instead
            // of 100: the body is not sent, and the connection is not reused.
            if let Ok(head) = tokio::time::timeout(EXPECT_WAIT, read_head(&mut connection)).await {
                let head = head?;
                if head.status != 100 {
                    read_body(&mut connection, &head).await?;
                    return Ok(head.status);
                }
            }
        }
        connection.get_mut().write_all(body).await?;
        let mut head = read_head(&mut connection).await?;
        while head.status == 100 {
            head = read_head(&mut connection).await?;
        }
        read_body(&mut connection, &head).await?;
        if !head.closes
            && let Ok(mut idle) = self.idle.lock()
        {
            idle.push(connection);
        }
        Ok(head.status)
    }
}

fn broken(what: &str) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidData, what.to_owned())
}

async fn read_head(connection: &mut Connection) -> std::io::Result<Head> {
    let mut line = String::new();
    if connection.read_line(&mut line).await? == 0 {
        return Err(broken("the connection closed before an answer"));
    }
    let status = line
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| broken("no status line"))?;
    let mut head = Head {
        status,
        content_length: None,
        chunked: false,
        closes: false,
    };
    loop {
        line.clear();
        if connection.read_line(&mut line).await? == 0 {
            return Err(broken("the connection closed inside an answer's head"));
        }
        let field = line.trim_end();
        if field.is_empty() {
            return Ok(head);
        }
        let Some((name, value)) = field.split_once(':') else {
            continue;
        };
        let value = value.trim();
        match name.to_ascii_lowercase().as_str() {
            "content-length" => head.content_length = value.parse().ok(),
            "transfer-encoding" => head.chunked = value.eq_ignore_ascii_case("chunked"),
            "connection" => head.closes = value.eq_ignore_ascii_case("close"),
            _ => {}
        }
    }
}

async fn read_body(connection: &mut Connection, head: &Head) -> std::io::Result<()> {
    if head.status == 100 || head.status == 204 || head.status == 304 {
        return Ok(());
    }
    if head.chunked {
        let mut line = String::new();
        loop {
            line.clear();
            connection.read_line(&mut line).await?;
            let size = usize::from_str_radix(line.trim().split(';').next().unwrap_or(""), 16)
                .map_err(|_| broken("a bad chunk size"))?;
            skip(connection, size).await?;
            line.clear();
            connection.read_line(&mut line).await?; // the chunk's CRLF, or the end's
            if size == 0 {
                return Ok(());
            }
        }
    }
    match head.content_length {
        Some(length) => skip(connection, length).await,
        None if head.closes => {
            let mut sink = Vec::new();
            connection.read_to_end(&mut sink).await.map(|_| ())
        }
        None => Err(broken("an answer with no length")),
    }
}

async fn skip(connection: &mut Connection, mut length: usize) -> std::io::Result<()> {
    let mut buffer = [0u8; 64 * 1024];
    while length > 0 {
        let want = length.min(buffer.len());
        let read = connection.read(&mut buffer[..want]).await?;
        if read == 0 {
            return Err(broken("the connection closed inside an answer's body"));
        }
        length -= read;
    }
    Ok(())
}
