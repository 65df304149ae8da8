# syntax=docker/dockerfile:1
# Build on the official Rust image, run on slim Debian as a non-root user.
FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock openapi.yaml ./
COPY src src
COPY benches benches
RUN cargo build --release --locked --bin meshfit

FROM debian:bookworm-slim
RUN apt-get update \
 && apt-get install -y --no-install-recommends curl \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --uid 10001 --no-create-home meshfit \
 && mkdir -p /var/cache/meshfit && chown meshfit /var/cache/meshfit
COPY --from=build /src/target/release/meshfit /usr/local/bin/meshfit
USER meshfit
# `docker stop` sends SIGTERM and kills after 10 s. The server stops within the grace period
# plus 5 s for connections to drain, so the grace here is 4 s; to give running jobs longer,
# raise both (e.g. `docker stop -t 40` or compose's stop_grace_period: 40s with 30000 here).
STOPSIGNAL SIGTERM
ENV MESHFIT_ADDR=0.0.0.0:8080 MESHFIT_LOG_FORMAT=json MESHFIT_SHUTDOWN_GRACE_MS=4000
EXPOSE 8080
HEALTHCHECK --interval=10s --timeout=3s --start-period=5s \
  CMD curl -fsS http://127.0.0.1:8080/healthz || exit 1
ENTRYPOINT ["meshfit"]
CMD ["serve"]
