//! The `citymesh` binary: parses the command line and hands over to the library.

use citymesh::cli::{Cli, Command};
use clap::Parser;

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command.unwrap_or_default() {
        Command::Serve(args) => citymesh::server::run(args).await,
        Command::Openapi => {
            println!("{}", citymesh::routes::openapi_json());
            Ok(())
        }
    }
}
