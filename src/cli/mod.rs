//! The command line, one file per command's options. Every flag can also be set with a
//! `CITYMESH_*` environment variable.

use clap::{Parser, Subcommand};

mod classify;
mod database;
mod export;
mod import;
mod infer_roofs;
mod options;
mod replicate;
mod scene;
mod serve;

pub use classify::*;
pub use database::DatabaseArgs;
pub use export::*;
pub use import::*;
pub use infer_roofs::*;
pub use options::*;
pub use replicate::*;
pub use scene::*;
pub use serve::*;

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
    Serve(Box<ServeArgs>),
    /// Print the OpenAPI description the server serves at /openapi.json.
    Openapi,
    /// Store OSM files (PBF, OSM XML or Overpass JSON, optionally .gz) as data tiles in the
    /// cache database, so `serve --offline` has buildings without any upstream.
    Import(ImportArgs),
    /// Follow an OpenStreetMap replication feed (`state.txt` and `AAA/BBB/CCC.osc.gz`): apply
    /// each change file to the imported data, each in one transaction with its sequence
    /// number, and drop the generated tiles over what changed.
    Replicate(ReplicateArgs),
    /// Make one scene from OSM and SRTM files into a GLB file (a batch export, no server):
    /// `citymesh scene --osm FILE --dem-dir DIR [--bbox ...] -o out.glb [--encoding meshopt]
    /// [--stats out.json]`.
    Scene(SceneArgs),
    /// Render a seeded set of synthetic roof crops (PNG) with labels, to train or test the roof
    /// classifier (training/roof_classifier/README.md).
    RenderRoofs(RenderRoofsArgs),
    /// Crop a labelled set of real roof images (a CSV of `file,label[,split,footprint_px_wkt]`)
    /// by citymesh's crop rule and write them as `render-roofs` writes renders, to train the
    /// roof classifier on real imagery (training/roof_classifier/README.md).
    CropLabelled(CropLabelledArgs),
    /// Fit a new head of the roof classifier on labelled crops of the user's imagery (a CSV of
    /// `file,label[,split,footprint_px_wkt]`), cross-validate it and write it for
    /// `classify-image --head`.
    AdaptRoofs(AdaptRoofsArgs),
    /// Classify the roof of one building per image (PNG or JPEG, any size, centred on the
    /// building): prints one JSON line per file with the class probabilities.
    ClassifyImage(ClassifyImageArgs),
    /// Write a static tree of tiles for a static file server or object store: a 3D Tiles
    /// tileset (`tileset.json`, `content/`, and `subtrees/` when implicit) or XYZ GLB tiles
    /// (`{z}/{x}/{y}.glb`),
    /// from the data the server would use (the serve options). Resumable: run the same command
    /// again after an interrupt and it writes only what is missing.
    Export(Box<ExportArgs>),
    /// Classify the roofs of OSM buildings from an XYZ imagery service, in the foreground: writes
    /// the predictions as GeoJSON and, with --all, how they agree with the roof:shape tags.
    Classify(ClassifyArgs),
    /// Predict the roof shapes of buildings without `roof:shape` from the tagged buildings of
    /// the same files (the roof prior, docs/extensions.md section 4): writes every untagged
    /// building with its class and probability as GeoJSON, and prints the prior's
    /// cross-validated accuracy on the tagged ones.
    InferRoofs(InferRoofsArgs),
}

impl Default for Command {
    fn default() -> Self {
        // No subcommand: serve with flags from the environment and the defaults.
        Command::Serve(Box::new(ServeArgs::parse_from(["serve"])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn serve_is_the_default_with_documented_defaults() {
        let Command::Serve(args) = Cli::parse_from(["citymesh"]).command.unwrap_or_default() else {
            panic!("no subcommand must mean serve");
        };
        assert_eq!(args.listen, "127.0.0.1:8080".parse().unwrap());
        assert_eq!(args.database.cache_db, "data/citymesh.sqlite");
        assert_eq!(args.database.database_url, None);
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
