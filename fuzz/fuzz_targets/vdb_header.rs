//! VDB header and metadata validation on arbitrary bytes: `validate.rs` must answer
//! every input with a listing or an error, never a panic, an abort or a huge allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nimbus::volume::asset::AssetLocation;
use std::sync::Arc;

fuzz_target!(|data: &[u8]| {
    // A .usdz member is validated from memory, the same code path as a file.
    let loc = AssetLocation::Packaged {
        package: "fuzz.usdz".into(),
        member: "fuzz.vdb".into(),
        bytes: Arc::new(data.to_vec()),
    };
    if let Ok(grids) = nimbus::volume::vdb::list_grids(&loc) {
        // Reading the trees with the pure-Rust reader is guarded by the same validation.
        for g in grids.iter().take(2) {
            let _ = nimbus::volume::vdb::read_float_grid_with(
                nimbus::volume::vdb::Reader::VdbRs,
                &loc,
                &g.name,
                None,
            );
        }
    }
});
