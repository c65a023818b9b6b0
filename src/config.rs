//! The service's settings, from flags or `TSPACE_*` environment variables (flags win).

use clap::{Args, ValueEnum};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// How request logs are written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines.
    #[default]
    Text,
    /// One JSON object per line, for log collectors.
    Json,
}

/// `tspace serve` flags.
#[derive(Clone, Debug, Args)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, env = "TSPACE_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: SocketAddr,
    /// Largest request body, in bytes (uploads with all their parts).
    #[arg(long, env = "TSPACE_BODY_LIMIT", default_value_t = 256 * 1024 * 1024)]
    pub body_limit: usize,
    /// Most triangles one request may ask tangents for (morph targets count).
    #[arg(long, env = "TSPACE_MAX_TRIANGLES", default_value_t = 16_000_000)]
    pub max_triangles: usize,
    /// Jobs that run at once (default: the number of cores).
    #[arg(long, env = "TSPACE_CONCURRENCY")]
    pub concurrency: Option<usize>,
    /// Jobs that may wait for a worker; beyond that, requests get 503 at once.
    #[arg(long, env = "TSPACE_QUEUE", default_value_t = 16)]
    pub queue: usize,
    /// Scene requests in progress at once, from the first byte of the body to the last byte of
    /// the answer (default: 2 × (concurrency + queue)); beyond that, requests get 503 before
    /// their body is buffered.
    #[arg(long, env = "TSPACE_IN_FLIGHT")]
    pub in_flight: Option<usize>,
    /// Seconds a request may take before it is answered with 504.
    #[arg(long, env = "TSPACE_TIMEOUT", default_value_t = 120)]
    pub timeout: u64,
    /// Seconds a client may take to send its request body (a slower one gets 408), and may go
    /// without reading any of its answer (then it is disconnected).
    #[arg(long, env = "TSPACE_READ_TIMEOUT", default_value_t = 30)]
    pub read_timeout: u64,
    /// Log format.
    #[arg(long, env = "TSPACE_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    pub log_format: LogFormat,
    /// A file of API keys, one per line (# starts a comment): when given, /v1/tangents,
    /// /v1/analyze and /v1/uv-layout answer only `Authorization: Bearer <key>` for one of them,
    /// else 401.
    #[arg(long, env = "TSPACE_API_KEYS_FILE")]
    pub api_keys_file: Option<PathBuf>,
}

/// The settings the server runs with.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    pub addr: SocketAddr,
    pub body_limit: usize,
    pub max_triangles: usize,
    pub concurrency: usize,
    pub queue: usize,
    /// Scene requests in progress at once (receiving, waiting, running or sending): this
    /// bounds how many uploads and answers the server holds, whatever the number of connections.
    pub in_flight: usize,
    pub timeout: Duration,
    /// How long a request body may take to arrive.
    pub read_timeout: Duration,
    pub log_format: LogFormat,
    /// Where the API keys are, when the scene routes require one (read at start).
    pub api_keys_file: Option<PathBuf>,
}

impl ServerConfig {
    /// Settings for tests and embedding: an ephemeral loopback port, small queue.
    pub fn local() -> Self {
        ServerConfig {
            addr: SocketAddr::from(([127, 0, 0, 1], 0)),
            body_limit: 64 * 1024 * 1024,
            max_triangles: 16_000_000,
            concurrency: 2,
            queue: 4,
            in_flight: 16,
            timeout: Duration::from_secs(60),
            read_timeout: Duration::from_secs(30),
            log_format: LogFormat::Text,
            api_keys_file: None,
        }
    }
}

impl From<ServeArgs> for ServerConfig {
    fn from(args: ServeArgs) -> Self {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let concurrency = args.concurrency.unwrap_or(cores).max(1);
        ServerConfig {
            addr: args.addr,
            body_limit: args.body_limit,
            max_triangles: args.max_triangles,
            concurrency,
            queue: args.queue,
            // Slow clients hold a slot until the read timeout; four per job the pool can hold
            // keeps a few of them from refusing everyone else.
            in_flight: args
                .in_flight
                .unwrap_or(2 * (concurrency + args.queue))
                .max(1),
            timeout: Duration::from_secs(args.timeout.max(1)),
            read_timeout: Duration::from_secs(args.read_timeout.max(1)),
            log_format: args.log_format,
            api_keys_file: args.api_keys_file,
        }
    }
}
