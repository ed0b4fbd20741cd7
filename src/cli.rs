//! The command line. Every flag can also be set with a `CITYMESH_*` environment variable.

use clap::{Parser, Subcommand};
use std::net::SocketAddr;
use std::path::PathBuf;

/// citymesh: 3D city meshes from OpenStreetMap and SRTM, on demand over HTTP.
#[derive(Debug, Parser)]
#[command(version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the HTTP server (the default when no subcommand is given).
    Serve(ServeArgs),
    /// Print the OpenAPI description the server serves at /openapi.json.
    Openapi,
}

impl Default for Command {
    fn default() -> Self {
        // No subcommand: serve with flags from the environment and the defaults.
        Command::Serve(ServeArgs::parse_from(["serve"]))
    }
}

/// Options of `citymesh serve`.
#[derive(Debug, Clone, Parser)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, env = "CITYMESH_LISTEN", default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,

    /// Directory of SRTM files (.hgt, .hgt.gz, .hgt.zip; SRTM3 or SRTM1; searched recursively).
    /// Areas without a file get flat ground at 0 m.
    #[arg(long, env = "CITYMESH_DEM_DIR", default_value = "data/dem")]
    pub dem_dir: PathBuf,

    /// SQLite file for cached data and generated tiles (created if missing; `:memory:` for none).
    #[arg(
        long,
        env = "CITYMESH_CACHE_DB",
        default_value = "data/citymesh.sqlite"
    )]
    pub cache_db: String,

    /// OSM data to serve buildings from: OSM PBF, OSM XML or Overpass JSON, optionally gzipped.
    /// Repeat the flag (or separate files with commas in CITYMESH_OSM) for several files.
    #[arg(long = "osm", env = "CITYMESH_OSM", value_delimiter = ',')]
    pub osm: Vec<PathBuf>,

    /// Log filter: error, warn, info, debug, trace, or a tracing directive like `citymesh=debug`.
    #[arg(long, env = "CITYMESH_LOG_LEVEL", default_value = "info")]
    pub log_level: String,

    /// Largest bounding box /scene.glb accepts, in square kilometres.
    #[arg(long, env = "CITYMESH_MAX_BBOX_KM2", default_value_t = 25.0)]
    pub max_bbox_km2: f64,

    /// Memory for parsed DEM files, in megabytes (an SRTM3 file takes 2.9 MB, SRTM1 26 MB).
    #[arg(long, env = "CITYMESH_DEM_CACHE_MB", default_value_t = 512)]
    pub dem_cache_mb: u64,

    /// Lowest zoom level /tiles serves.
    #[arg(long, env = "CITYMESH_MIN_ZOOM", default_value_t = 12)]
    pub min_zoom: u8,

    /// Highest zoom level /tiles serves.
    #[arg(long, env = "CITYMESH_MAX_ZOOM", default_value_t = 20)]
    pub max_zoom: u8,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serve_is_the_default_with_documented_defaults() {
        let Command::Serve(args) = Cli::parse_from(["citymesh"]).command.unwrap_or_default() else {
            panic!("no subcommand must mean serve");
        };
        assert_eq!(args.listen, "127.0.0.1:8080".parse().unwrap());
        assert_eq!(args.cache_db, "data/citymesh.sqlite");
        assert_eq!((args.min_zoom, args.max_zoom), (12, 20));
    }

    #[test]
    fn flags_parse() {
        let cli = Cli::parse_from([
            "citymesh",
            "serve",
            "--listen",
            "0.0.0.0:9000",
            "--dem-dir",
            "/x",
        ]);
        let Some(Command::Serve(args)) = cli.command else {
            panic!()
        };
        assert_eq!(args.listen.port(), 9000);
        assert_eq!(args.dem_dir, PathBuf::from("/x"));
    }
}
