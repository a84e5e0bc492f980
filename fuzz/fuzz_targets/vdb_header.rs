//! VDB header and metadata validation on arbitrary bytes: `validate.rs` must answer
//! every input with a listing or an error, never a panic, an abort or a huge allocation;
//! so must Nimbus' own tree reader (`tree.rs`) on whatever validation lets through.
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
        use nimbus::volume::vdb::{read_float_grid_with, read_vec3s_grid_with, Reader};
        for g in grids.iter().take(2) {
            if g.value_type == "Tree_vec3s_5_4_3" {
                let _ = read_vec3s_grid_with(Reader::Rust, &loc, &g.name, None);
            } else {
                let _ = read_float_grid_with(Reader::Rust, &loc, &g.name, None);
            }
        }
    }
});
