//! What several commands read besides their flags: the user's cache folder and a chains
//! file.

use super::exit::Failure;
use std::path::Path;

/// The user's cache root, unless `--no-cache` (or no cache directory is known).
pub(super) fn user_cache(no_cache: bool) -> Option<std::path::PathBuf> {
    match no_cache {
        true => None,
        false => crate::store::cache::Cache::user().map(|c| c.root().to_path_buf()),
    }
}

/// The chains file: `path`'s, or the embedded pipelines/chains.toml.
pub(super) fn chain_file(path: Option<&Path>) -> Result<crate::sim::chain::ChainFile, Failure> {
    use crate::sim::SimError;
    Ok(match path {
        None => crate::sim::chain::ChainFile::shipped(),
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .map_err(|e| SimError::Read(format!("{}: {e}", p.display())))?;
            crate::sim::chain::ChainFile::parse(&text).map_err(SimError::from)?
        }
    })
}
