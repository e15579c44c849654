# lockstep-server in a container: build with the Rust toolchain, run from a
# slim base as a non-root user. Mount a volume at /data for replays (and the
# dev certificate, or give --cert/--key files there); the root filesystem
# can then be read-only. See docs/deploy.md.

FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked -p lockstep \
        --bin lockstep-server --bin lockstep-bot --bin lockstep

FROM debian:bookworm-slim
RUN useradd --system --uid 10001 --no-create-home --shell /usr/sbin/nologin lockstep
COPY --from=build /src/target/release/lockstep-server /usr/local/bin/lockstep-server
COPY --from=build /src/target/release/lockstep-bot /usr/local/bin/lockstep-bot
COPY --from=build /src/target/release/lockstep /usr/local/bin/lockstep
USER 10001
VOLUME ["/data"]
ENV LOCKSTEP_LISTEN=0.0.0.0:4433 \
    LOCKSTEP_METRICS=0.0.0.0:9100 \
    LOCKSTEP_REPLAY_DIR=/data/replays \
    LOCKSTEP_CERT_OUT=/data/dev-cert.pem \
    RUST_LOG=info
EXPOSE 4433/udp 9100/tcp
ENTRYPOINT ["lockstep-server"]
