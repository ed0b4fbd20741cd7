# citymesh server image. Build: docker build -t citymesh .
# Run:   docker run -p 8080:8080 -v /path/to/srtm:/data/dem citymesh

FROM rust:1-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY crates ./crates
COPY src ./src
COPY migrations ./migrations
RUN cargo build --release --locked --bin citymesh

# The pages' JavaScript libraries (three, 3d-tiles-renderer, CesiumJS), served under /vendor/.
FROM node:20-bookworm-slim AS assets
WORKDIR /assets
COPY package.json package-lock.json ./
RUN npm ci --no-audit --no-fund

FROM debian:bookworm-slim
RUN apt-get update && apt-get install -y --no-install-recommends ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --home /data citymesh && mkdir -p /data/dem && chown -R citymesh /data
COPY --from=build /src/target/release/citymesh /usr/local/bin/citymesh
COPY --from=assets /assets/node_modules/three /usr/share/citymesh/assets/three
COPY --from=assets /assets/node_modules/3d-tiles-renderer /usr/share/citymesh/assets/3d-tiles-renderer
COPY --from=assets /assets/node_modules/cesium /usr/share/citymesh/assets/cesium
USER citymesh
WORKDIR /data
ENV CITYMESH_LISTEN=0.0.0.0:8080 \
    CITYMESH_DEM_DIR=/data/dem \
    CITYMESH_CACHE_DB=/data/citymesh.sqlite \
    CITYMESH_ASSETS_DIR=/usr/share/citymesh/assets
EXPOSE 8080
ENTRYPOINT ["citymesh"]
CMD ["serve"]
