//! `kinecal irb120 DATA_DIR`: real-data calibration of the ABB IRB 120 (being written).
use clap::Args;
use std::path::PathBuf;

/// Arguments of `kinecal irb120`.
#[derive(Args, Debug)]
pub struct Irb120Args {
    /// Folder with joints_deg.csv, smr1..3.csv and base1..3.csv.
    pub data: PathBuf,
}

/// Run the command.
pub fn run(args: Irb120Args) -> anyhow::Result<()> {
    anyhow::bail!("{}: the IRB 120 pipeline is not wired yet", args.data.display())
}
