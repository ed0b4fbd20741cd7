# citymesh server image. Build: docker build -t citymesh .
# Run:   docker run -p 8080:8080 -v /path/to/srtm:/data/dem citymesh

FROM rust:1-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY crates ./crates
COPY src ./src
COPY migrations ./migrations
RUN cargo build --release --locked --bin citymesh

FROM debian:bookworm-slim
RUN useradd --system --home /data citymesh && mkdir -p /data/dem && chown -R citymesh /data
COPY --from=build /src/target/release/citymesh /usr/local/bin/citymesh
USER citymesh
WORKDIR /data
ENV CITYMESH_LISTEN=0.0.0.0:8080 \
    CITYMESH_DEM_DIR=/data/dem \
    CITYMESH_CACHE_DB=/data/citymesh.sqlite
EXPOSE 8080
ENTRYPOINT ["citymesh"]
CMD ["serve"]
