//! Options of `citymesh infer-roofs`: the roof prior learned from OSM files' own tags.

use clap::Parser;
use std::path::PathBuf;

/// Options of `citymesh infer-roofs`.
#[derive(Debug, Clone, Parser)]
pub struct InferRoofsArgs {
    /// OSM data: OSM PBF, OSM XML or Overpass JSON, optionally gzipped (repeat for several). The
    /// prior learns from every tagged building of all files, as `serve --osm` does.
    #[arg(long, required = true)]
    pub osm: Vec<PathBuf>,

    /// Write only the buildings whose outline touches this box (minLon,minLat,maxLon,maxLat).
    /// The prior still learns from all files.
    #[arg(long)]
    pub bbox: Option<String>,

    /// The GeoJSON file to write: one feature per building without `roof:shape`.
    #[arg(long, short)]
    pub out: PathBuf,
}
