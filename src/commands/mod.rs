//! The commands' bodies, one file each; `crate::cli` holds their options. Each reads its
//! options, calls the library (server, sources, roofs, pipeline) and reports.

pub mod adapt_roofs;
pub mod classify;
pub mod classify_image;
pub mod export;
pub mod import;
pub mod infer_roofs;
pub mod replicate;
pub mod scene;
pub mod serve;

use crate::cli::Command;
use crate::roofs::classifier::{ClassifierError, load_onnx, onnx::OnnxClassifier};
use std::sync::Arc;

/// The ONNX classifier the command-line options name (`--onnxruntime-lib`, `--roof-model`,
/// `--roof-passes`).
pub fn load_classifier(
    args: &crate::cli::ClassifierArgs,
) -> Result<Arc<OnnxClassifier>, ClassifierError> {
    load_onnx(
        args.onnxruntime_lib.as_deref(),
        args.roof_model.as_deref(),
        args.roof_passes,
    )
}

/// Runs `command`: on a multi-threaded runtime when it serves or waits on the network or the
/// database, on the calling thread when it only computes and writes files.
pub fn run(command: Command) -> anyhow::Result<()> {
    match command {
        // Serving and the commands that talk to the database or the network need the runtime;
        // batch commands run on this thread and start none (it shows in whole-process timings).
        command @ (Command::Serve(_)
        | Command::Import(_)
        | Command::Replicate(_)
        | Command::Classify(_)
        | Command::Export(_)) => runtime(command),
        Command::AdaptRoofs(args) if args.labels.is_none() => runtime(Command::AdaptRoofs(args)),
        command => run_batch(command),
    }
}

/// Runs `command` on a multi-threaded runtime.
fn runtime(command: Command) -> anyhow::Result<()> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?
        .block_on(run_async(command))
}

/// The commands that serve or wait on the network and the database (on the runtime `main`
/// starts).
async fn run_async(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Serve(args) => serve::run(*args).await,
        Command::Replicate(args) => replicate::run(args).await,
        Command::Import(args) if args.changes.is_some() => {
            let db = args.database.open().await?;
            let path = args.changes.clone().unwrap_or_default();
            let report = replicate::apply_file(&path, &db).await?;
            println!("{}: {}", path.display(), replicate::describe(&report));
            Ok(())
        }
        Command::Import(args) => {
            let db = args.database.open().await?;
            let options = crate::source::data_tiles::import::ImportOptions {
                memory_bytes: args.memory_mb << 20,
                temp_dir: args.temp_dir.clone(),
                quiet: args.quiet,
            };
            let report = import::import_with(&args.files, &db, &options).await?;
            println!(
                "imported {} buildings ({} skipped) into {} data tiles ({} changed; {} generated tiles dropped) in {}: {} bytes stored ({:.0} per building), {:.1} s ({:.0} buildings/s)",
                report.buildings,
                report.skipped,
                report.data_tiles,
                report.changed_data_tiles,
                report.tiles_invalidated,
                args.database.describe(),
                report.stored_bytes,
                report.stored_bytes as f64 / report.buildings.max(1) as f64,
                report.seconds,
                report.buildings as f64 / report.seconds.max(1e-3),
            );
            // Which buildings were left out, and why (a building over 2 km, a node out of
            // range, missing nodes, ...), the first hundred by id.
            const SHOWN: usize = 100;
            for (id, why) in report.skips.iter().take(SHOWN) {
                eprintln!("skipped {id}: {why}");
            }
            if report.skips.len() > SHOWN {
                eprintln!("... and {} more skipped", report.skips.len() - SHOWN);
            }
            Ok(())
        }
        Command::Export(mut args) => {
            // One generation slot per worker: an export waits for its own slots, never for
            // `--generation-wait-ms`.
            let workers = args.worker_count();
            args.serve.max_generations = Some(workers);
            // A generator alone: no tile cache, listener or roof workers.
            let opened =
                crate::server::open_generator(&args.serve, crate::clock::Clock::system(), "export")
                    .await?;
            export::run(&opened, &args).await?;
            Ok(())
        }
        Command::Classify(args) => {
            let summary = classify::run(&args).await?;
            println!("{summary}");
            Ok(())
        }
        Command::AdaptRoofs(args) if args.labels.is_none() => {
            if adapt_roofs::run_osm(&args).await? {
                Ok(())
            } else {
                std::process::exit(1)
            }
        }
        command => run_batch(command),
    }
}

/// The commands that only compute and write files, on the calling thread.
fn run_batch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Scene(args) => {
            let report = scene::export_scene(&args)?;
            eprintln!(
                "{} buildings ({} skipped), {} bytes, generated in {:.1} ms",
                report.buildings, report.skipped, report.bytes, report.generation_ms
            );
            Ok(())
        }
        Command::InferRoofs(args) => {
            let report = infer_roofs::infer_roofs(&args)?;
            println!("{report}");
            Ok(())
        }
        Command::Openapi => {
            println!("{}", crate::routes::openapi_json());
            Ok(())
        }
        Command::RenderRoofs(args) => {
            let palette = citymesh_core::roof_image::synthetic::Palette::from_name(&args.palette)
                .ok_or_else(|| {
                anyhow::anyhow!(
                    "--palette must be training or holdout, not {:?}",
                    args.palette
                )
            })?;
            let spec = crate::roofs::classifier::training_set::TrainingSetSpec {
                osm: args.osm,
                procedural_seeds: args.procedural,
                count: args.count,
                seed: args.seed,
                palette,
                out: args.out,
            };
            let report = crate::roofs::classifier::training_set::render_training_set(&spec)?;
            println!(
                "wrote {} crops (flat {}, gabled {}, hipped {}; {} could not be built) to {}",
                report.written,
                report.per_class[0],
                report.per_class[1],
                report.per_class[2],
                report.failed,
                spec.out.display()
            );
            Ok(())
        }
        Command::CropLabelled(args) => {
            let labels = crate::roofs::classifier::labelled::read_labels(&args.labels)?;
            let report = crate::roofs::classifier::training_set::write_labelled_set(
                &labels,
                args.split.as_deref(),
                &args.out,
            )?;
            println!(
                "wrote {} crops (flat {}, gabled {}, hipped {}; {} could not be cropped) to {}",
                report.written,
                report.per_class[0],
                report.per_class[1],
                report.per_class[2],
                report.failed,
                args.out.display()
            );
            Ok(())
        }
        Command::AdaptRoofs(args) if args.labels.is_some() => {
            if adapt_roofs::run_labels(&args)? {
                Ok(())
            } else {
                std::process::exit(1)
            }
        }
        Command::ClassifyImage(args) => {
            if classify_image::run(&args)? {
                Ok(())
            } else {
                std::process::exit(1)
            }
        }
        Command::Serve(_)
        | Command::Import(_)
        | Command::Replicate(_)
        | Command::Classify(_)
        | Command::Export(_)
        | Command::AdaptRoofs(_) => {
            anyhow::bail!("this command needs the async runtime (main starts it)")
        }
    }
}
