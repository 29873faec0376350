//! `hil-sim golden`: records the golden traces the Cortex-M4F must reproduce bit for bit
//! ([`crate::analysis::golden`]), one per reference case of `ema::control::trace::CASES`, into
//! `tests/golden/` of the workspace (or `--dir`).

use std::io::Write;
use std::path::PathBuf;

use crate::analysis::golden::write_all;

/// Arguments of `golden`.
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// Folder the traces go to.
    #[arg(long, default_value = "tests/golden")]
    pub dir: PathBuf,
}

/// Writes the traces.
///
/// # Errors
/// A missing folder (run it from the workspace root, or give `--dir`); a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Vec<PathBuf>> {
    anyhow::ensure!(
        args.dir.is_dir(),
        "--dir = {}: no such folder (run from the workspace root, or give --dir)",
        args.dir.display()
    );
    let files = write_all(&args.dir)?;
    super::list_files(out, &files)?;
    Ok(files)
}
