//! Where an asset's bytes live: a file, or a member of a .usdz package already read
//! through USD's resolver. Plain data the stage loader resolves and the VDB readers open.

use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq)]
pub enum AssetLocation {
    File(PathBuf),
    /// A member of a .usdz package, with its bytes already read through the resolver.
    Packaged {
        package: PathBuf,
        member: String,
        bytes: std::sync::Arc<Vec<u8>>,
    },
}

impl std::fmt::Display for AssetLocation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AssetLocation::File(p) => write!(f, "{}", p.display()),
            AssetLocation::Packaged {
                package, member, ..
            } => {
                write!(f, "{}[{}]", package.display(), member)
            }
        }
    }
}
