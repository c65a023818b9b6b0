# tspace: the HTTP service by default (`docker run -p 8080:8080 tspace`), or the command line
# (`docker run --rm -v "$PWD:/data" -u "$(id -u):$(id -g)" tspace process model.gltf`).

# ---- build ----
FROM rust:1-slim-bookworm AS build
# The `meshopt` crate (EXT_meshopt_compression output) compiles meshoptimizer's C++; the slim
# image has a C compiler only. The binary then links libstdc++, which debian:bookworm-slim has.
RUN apt-get update \
    && apt-get install -y --no-install-recommends g++ \
    && rm -rf /var/lib/apt/lists/*
WORKDIR /src

# The workspace as it is (manifests, the root package and crates/; benches/ because the root
# manifest names its benches; assets/ for the font built into the binary), so there is no
# hand-made stub to drift from the manifests.
# Dependencies are kept between builds in cache mounts rather than in a stub layer: a change to
# the sources rebuilds only the workspace's own crates.
COPY Cargo.toml Cargo.lock ./
COPY crates ./crates
COPY benches ./benches
COPY assets ./assets
COPY src ./src
# The image's binary carries no debug information or symbols: about 18 MB, where the release
# profile's, with its line tables, is about 90 MB (measured 2026-11-24).
ENV CARGO_PROFILE_RELEASE_DEBUG=false CARGO_PROFILE_RELEASE_STRIP=symbols
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked --bin tspace \
    && cp target/release/tspace /usr/local/bin/tspace

# ---- run ----
FROM debian:bookworm-slim
RUN groupadd --system --gid 10001 tspace \
    && useradd --system --uid 10001 --gid tspace --no-create-home --home-dir /nonexistent \
        --shell /usr/sbin/nologin tspace
COPY --from=build /usr/local/bin/tspace /usr/local/bin/tspace
# The binary carries a subset of DejaVu Sans (for the UV-layout PNGs); its licence goes with it.
COPY assets/fonts/DejaVuSans-LICENSE /usr/share/doc/tspace/DejaVuSans-LICENSE
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
