//! The `citymesh` binary: parses the command line and hands over to the library.

use citymesh::cli::{Cli, Command};
use clap::Parser;

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command.unwrap_or_default() {
        Command::Serve(args) => citymesh::server::run(*args).await,
        Command::Openapi => {
            println!("{}", citymesh::routes::openapi_json());
            Ok(())
        }
        Command::Import(args) => {
            let report = citymesh::import::import(&args.files, &args.cache_db, args.quiet).await?;
            println!(
                "imported {} buildings ({} skipped) into {} data tiles ({} changed; {} generated tiles dropped) in {}",
                report.buildings,
                report.skipped,
                report.data_tiles,
                report.changed_data_tiles,
                report.tiles_invalidated,
                args.cache_db
            );
            Ok(())
        }
    }
}
