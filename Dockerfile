# syntax=docker/dockerfile:1
# Build on the official Rust image, run on slim Debian as a non-root user.
FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock openapi.yaml ./
COPY src src
COPY benches benches
# The registry and target/ live in BuildKit cache mounts, so a change to src/ recompiles
# meshfit alone, not its ~300 dependencies. The image's binary is stripped: the profile's
# line tables are for profiling on a developer's machine, not for a container.
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    CARGO_PROFILE_RELEASE_DEBUG=false CARGO_PROFILE_RELEASE_STRIP=symbols \
    cargo build --release --locked --bin meshfit \
 && cp target/release/meshfit /usr/local/bin/meshfit

FROM debian:bookworm-slim
RUN useradd --system --uid 10001 --no-create-home meshfit \
 && mkdir -p /var/cache/meshfit && chown meshfit /var/cache/meshfit
COPY --from=build /usr/local/bin/meshfit /usr/local/bin/meshfit
USER meshfit
# `docker stop` sends SIGTERM and kills after 10 s. The server stops within the grace period
# plus 5 s for connections to drain, so the grace here is 4 s; to give running jobs longer,
# raise both (e.g. `docker stop -t 40` or compose's stop_grace_period: 40s with 30000 here).
STOPSIGNAL SIGTERM
ENV MESHFIT_ADDR=0.0.0.0:8080 MESHFIT_LOG_FORMAT=json MESHFIT_SHUTDOWN_GRACE_MS=4000
EXPOSE 8080
# `meshfit health` asks GET /healthz at MESHFIT_ADDR, so the check follows a changed address.
HEALTHCHECK --interval=10s --timeout=5s --start-period=5s CMD ["meshfit", "health"]
ENTRYPOINT ["meshfit"]
CMD ["serve"]
