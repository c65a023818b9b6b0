# tspace: the HTTP service by default (`docker run -p 8080:8080 tspace`), or the command line
# (`docker run --rm -v "$PWD:/data" -u "$(id -u):$(id -g)" tspace process model.gltf`).

# ---- build ----
FROM rust:1-slim-bookworm AS build
WORKDIR /src

# Dependencies first, against stub sources, so that this layer is rebuilt only when
# Cargo.toml or Cargo.lock change. (Cargo.toml names benches/tangents.rs, so it must exist.)
COPY Cargo.toml Cargo.lock ./
RUN mkdir -p src benches \
    && echo 'fn main() {}' > src/main.rs \
    && touch src/lib.rs \
    && for bench in tangents http; do echo 'fn main() {}' > benches/$bench.rs; done \
    && cargo build --release --locked --bin tspace \
    && rm -rf src

# Then the crate itself. COPY keeps the files' own modification times, which may be older than
# the stub build's; touching the crate roots makes Cargo rebuild them.
COPY src ./src
RUN touch src/lib.rs src/main.rs \
    && cargo build --release --locked --bin tspace

# ---- run ----
FROM debian:bookworm-slim
RUN groupadd --system --gid 10001 tspace \
    && useradd --system --uid 10001 --gid tspace --no-create-home --home-dir /nonexistent \
        --shell /usr/sbin/nologin tspace
COPY --from=build /src/target/release/tspace /usr/local/bin/tspace
WORKDIR /data
USER 10001:10001
ENV TSPACE_ADDR=0.0.0.0:8080
EXPOSE 8080
# `tspace healthcheck` GETs /healthz on TSPACE_ADDR (0.0.0.0 means this host) with the standard
# library; the image needs no curl.
HEALTHCHECK --interval=30s --timeout=5s --start-period=5s --retries=3 \
    CMD ["tspace", "healthcheck", "--timeout", "4"]
ENTRYPOINT ["tspace"]
CMD ["serve"]
