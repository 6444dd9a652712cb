//! `towernav-sim`: export the simulated world for the landmark database.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};
use towernav_sim::World;

#[derive(Parser)]
#[command(about = "towernav simulator: worlds and flights with exact truth")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write the seed field's 18 towers as a landmark CSV.
    World {
        /// Output CSV path; `-` for standard output.
        #[arg(long, default_value = "-")]
        out: PathBuf,
    },
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::World { out } => {
            let landmarks = World::seed_field().landmarks();
            if out.as_os_str() == "-" {
                towernav_landmark_db::export_csv(&landmarks, std::io::stdout().lock())?;
            } else {
                let file = std::fs::File::create(&out)
                    .with_context(|| format!("creating {}", out.display()))?;
                towernav_landmark_db::export_csv(&landmarks, file)
                    .with_context(|| format!("writing {}", out.display()))?;
                eprintln!("wrote {} towers to {}", landmarks.len(), out.display());
            }
        }
    }
    Ok(())
}
