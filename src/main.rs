//! The `citymesh` binary: parses the command line and hands over to the library.

use citymesh::cli::{Cli, Command};
use clap::Parser;

// mimalloc keeps freed pages for the next request instead of handing a scene's buffers back to
// the kernel and faulting them in again (a fifth of generation time with glibc's allocator).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Runs the command; an error is printed as one message with its causes (`error: ...: ...`),
/// never a backtrace, and the exit status is 1.
fn main() -> std::process::ExitCode {
    match command(Cli::parse().command.unwrap_or_default()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn command(command: Command) -> anyhow::Result<()> {
    match command {
        // Serving and the commands that talk to the database or the network need the runtime;
        // batch commands run on this thread and start none (it shows in whole-process timings).
        command @ (Command::Serve(_)
        | Command::Import(_)
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
        .block_on(run(command))
}

/// The commands that serve or wait on the network and the database (on the runtime `main`
/// starts).
async fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Serve(args) => citymesh::server::run(*args).await,
        Command::Import(args) => {
            let db = args.database.open().await?;
            let report = citymesh::import::import_into(&args.files, &db, args.quiet).await?;
            println!(
                "imported {} buildings ({} skipped) into {} data tiles ({} changed; {} generated tiles dropped) in {}",
                report.buildings,
                report.skipped,
                report.data_tiles,
                report.changed_data_tiles,
                report.tiles_invalidated,
                args.database.describe()
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
        Command::Export(args) => {
            let state = citymesh::server::build_state(&args.serve).await?;
            citymesh::export::run(&state, &args).await?;
            Ok(())
        }
        Command::Classify(args) => {
            let summary = citymesh::classifier::classify_area::run(&args).await?;
            println!("{summary}");
            Ok(())
        }
        Command::AdaptRoofs(args) if args.labels.is_none() => {
            if citymesh::classifier::adapt::run_osm(&args).await? {
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
            let report = citymesh::scene_file::export_scene(&args)?;
            eprintln!(
                "{} buildings ({} skipped), {} bytes, generated in {:.1} ms",
                report.buildings, report.skipped, report.bytes, report.generation_ms
            );
            Ok(())
        }
        Command::InferRoofs(args) => {
            let report = citymesh::roof_prior::infer_roofs(&args)?;
            println!("{report}");
            Ok(())
        }
        Command::Openapi => {
            println!("{}", citymesh::routes::openapi_json());
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
            let spec = citymesh::classifier::training_set::TrainingSetSpec {
                osm: args.osm,
                procedural_seeds: args.procedural,
                count: args.count,
                seed: args.seed,
                palette,
                out: args.out,
            };
            let report = citymesh::classifier::training_set::render_training_set(&spec)?;
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
            let labels = citymesh::classifier::labelled::read_labels(&args.labels)?;
            let report = citymesh::classifier::training_set::write_labelled_set(
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
            if citymesh::classifier::adapt::run_labels(&args)? {
                Ok(())
            } else {
                std::process::exit(1)
            }
        }
        Command::ClassifyImage(args) => {
            if citymesh::classifier::classify_image::run(&args)? {
                Ok(())
            } else {
                std::process::exit(1)
            }
        }
        Command::Serve(_)
        | Command::Import(_)
        | Command::Classify(_)
        | Command::Export(_)
        | Command::AdaptRoofs(_) => {
            anyhow::bail!("this command needs the async runtime (main starts it)")
        }
    }
}
