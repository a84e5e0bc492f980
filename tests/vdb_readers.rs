//! VDB reader tests: writer round trips through both readers, cross-checks of the
//! OpenVDB bridge against Nimbus' own Rust reader on real production files (grids and
//! renders, bit for bit), and malformed input.
//!
//! Run with `cargo test --release --test vdb_readers`. Tests that need OpenVDB check
//! `Reader::OpenVdb.available()`; CI builds with `NIMBUS_OPENVDB=require`.

mod common;

use glam::{DMat4, DVec3};
use nimbus::volume::asset::AssetLocation;
use nimbus::volume::grid::{RawGrid, RawLeaf, RawTile};
use nimbus::volume::vdb::{
    active_reader, list_grids, list_grids_with, read_float_grid, read_float_grid_with,
    read_vec3s_grid_with, write_float_grid, write_float_grid_bytes, write_float_grids, GridInfo,
    Reader, VdbError, READER_ENV,
};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn readers() -> Vec<Reader> {
    [Reader::OpenVdb, Reader::Rust]
        .into_iter()
        .filter(|r| r.available())
        .collect()
}

/// Deterministic value noise in [0, 1).
fn hash01(p: [i32; 3]) -> f32 {
    let mut x = (p[0] as u32 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (p[1] as u32 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (p[2] as u32 as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    x ^= x >> 29;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 32;
    (x >> 40) as f32 / (1u64 << 24) as f32
}

/// A noisy sphere of radius `r` voxels around `c`, as leaves, plus tiles on every
/// tree level (active and inactive) away from the sphere.
fn noisy_sphere(c: [i32; 3], r: i32, index_to_world: DMat4) -> RawGrid {
    let mut leaves = Vec::new();
    let lo = |a: usize| (c[a] - r).div_euclid(8) * 8;
    let hi = |a: usize| (c[a] + r).div_euclid(8) * 8;
    let mut x0 = lo(0);
    while x0 <= hi(0) {
        let mut y0 = lo(1);
        while y0 <= hi(1) {
            let mut z0 = lo(2);
            while z0 <= hi(2) {
                let mut values = vec![0.0f32; 512];
                let mut active = [0u64; 8];
                for off in 0..512usize {
                    let p = [
                        x0 + (off >> 6) as i32,
                        y0 + ((off >> 3) & 7) as i32,
                        z0 + (off & 7) as i32,
                    ];
                    let d2: i32 = (0..3).map(|a| (p[a] - c[a]).pow(2)).sum();
                    let d = (d2 as f32).sqrt() / r as f32;
                    if d < 1.0 {
                        values[off] = (1.0 - d) * (0.5 + hash01(p));
                        active[off / 64] |= 1 << (off % 64);
                    } else if off % 7 == 0 {
                        // Inactive voxels with non-background values must survive too.
                        values[off] = -0.25;
                    }
                }
                if active.iter().any(|&w| w != 0) {
                    leaves.push(RawLeaf {
                        origin: [x0, y0, z0],
                        values,
                        active,
                    });
                }
                z0 += 8;
            }
            y0 += 8;
        }
        x0 += 8;
    }
    let tiles = vec![
        RawTile {
            origin: [200, 8, 16],
            dim: 8,
            value: 0.75,
            active: true,
        },
        RawTile {
            origin: [208, 8, 16],
            dim: 8,
            value: 0.5,
            active: false,
        },
        RawTile {
            origin: [-256, 128, 0],
            dim: 128,
            value: 0.125,
            active: true,
        },
        RawTile {
            origin: [8192, -4096, 0],
            dim: 4096,
            value: 2.0,
            active: true,
        },
    ];
    RawGrid {
        name: "density".into(),
        class: "fog volume".into(),
        background: 0.0,
        leaves,
        tiles,
        index_to_world,
    }
}

fn scale_translate(s: DVec3, t: DVec3) -> DMat4 {
    DMat4::from_translation(t) * DMat4::from_scale(s)
}

fn sorted_leaves(g: &RawGrid) -> Vec<(Vec<i32>, Vec<u32>, [u64; 8])> {
    let mut v: Vec<_> = g
        .leaves
        .iter()
        .map(|l| {
            (
                l.origin.to_vec(),
                l.values.iter().map(|f| f.to_bits()).collect(),
                l.active,
            )
        })
        .collect();
    v.sort();
    v
}

fn sorted_tiles(g: &RawGrid) -> Vec<(Vec<i32>, i32, u32, bool)> {
    let mut v: Vec<_> = g
        .tiles
        .iter()
        .map(|t| (t.origin.to_vec(), t.dim, t.value.to_bits(), t.active))
        .collect();
    v.sort();
    v
}

/// Asserts `got` holds exactly `want`'s data (leaves bit for bit, tiles, transform).
fn assert_same_grid(want: &RawGrid, got: &RawGrid, who: &str) {
    assert_eq!(got.checksum(), want.checksum(), "{who}: checksum");
    assert_eq!(
        got.active_voxel_count(),
        want.active_voxel_count(),
        "{who}: active voxels"
    );
    assert_eq!(got.index_to_world, want.index_to_world, "{who}: transform");
    assert_eq!(
        got.background.to_bits(),
        want.background.to_bits(),
        "{who}: background"
    );
    assert_eq!(got.name, want.name, "{who}: name");
    assert_eq!(got.class, want.class, "{who}: class");
    assert!(
        sorted_leaves(got) == sorted_leaves(want),
        "{who}: leaves differ"
    );
    assert_eq!(sorted_tiles(got), sorted_tiles(want), "{who}: tiles");
}

#[test]
fn writer_round_trip_both_readers() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "uniform",
            noisy_sphere(
                [3, -5, 7],
                21,
                scale_translate(DVec3::splat(0.05), DVec3::new(1.5, -2.0, 0.25)),
            ),
        ),
        (
            "nonuniform",
            noisy_sphere(
                [-40, 0, 12],
                13,
                scale_translate(DVec3::new(0.1, 0.2, 0.3), DVec3::ZERO),
            ),
        ),
    ];
    for (label, grid) in cases {
        assert!(grid.leaves.len() > 20 && grid.active_voxel_count() > 1000);
        let path = dir.path().join(format!("{label}.vdb"));
        write_float_grid(&path, &grid).unwrap();
        let loc = AssetLocation::File(path.clone());
        let listed = list_grids(&loc).unwrap();
        assert_eq!(listed.len(), 1);
        assert_eq!(listed[0].name, "density");
        assert_eq!(listed[0].value_type, "Tree_float_5_4_3");
        assert_eq!(listed[0].active_voxels, Some(grid.active_voxel_count()));
        for reader in readers() {
            let got = read_float_grid_with(reader, &loc, "density", None)
                .unwrap_or_else(|e| panic!("{label} via {}: {e}", reader.name()));
            assert_same_grid(&grid, &got, &format!("{label} via {}", reader.name()));
            // Any-name and index selection find the same single grid.
            let any = read_float_grid_with(reader, &loc, "", Some(0)).unwrap();
            assert_eq!(any.checksum(), grid.checksum());
        }
        // Packaged (.usdz member) bytes read the same as the file.
        let bytes = write_float_grid_bytes(&grid).unwrap();
        assert_eq!(
            bytes,
            std::fs::read(&path).unwrap(),
            "writer output is deterministic"
        );
        let packaged = AssetLocation::Packaged {
            package: dir.path().join("scene.usdz"),
            member: format!("{label}.vdb"),
            bytes: Arc::new(bytes),
        };
        for reader in readers() {
            let got = read_float_grid_with(reader, &packaged, "density", None).unwrap();
            assert_same_grid(
                &grid,
                &got,
                &format!("{label} packaged via {}", reader.name()),
            );
        }
        if Reader::OpenVdb.available() {
            let ov = list_grids_with(Reader::OpenVdb, &loc).unwrap();
            assert_eq!(ov.len(), 1);
            assert_eq!(ov[0].name, "density");
            assert_eq!(ov[0].value_type, "Tree_float_5_4_3");
            assert_eq!(ov[0].active_voxels, Some(grid.active_voxel_count()));
        }
    }
}

#[test]
fn writer_rejects_what_it_cannot_write() {
    let mut g = noisy_sphere([0, 0, 0], 5, DMat4::IDENTITY);
    g.index_to_world = DMat4::from_rotation_z(0.3);
    let e = write_float_grid_bytes(&g).unwrap_err().to_string();
    assert!(e.contains("not a scale + translation"), "{e}");
    let mut g = noisy_sphere([0, 0, 0], 5, DMat4::IDENTITY);
    g.leaves[0].origin[1] += 3;
    assert!(write_float_grid_bytes(&g)
        .unwrap_err()
        .to_string()
        .contains("multiple of 8"));
    let mut g = noisy_sphere([0, 0, 0], 5, DMat4::IDENTITY);
    g.tiles.push(RawTile {
        origin: g.leaves[0].origin,
        dim: 8,
        value: 1.0,
        active: true,
    });
    assert!(write_float_grid_bytes(&g)
        .unwrap_err()
        .to_string()
        .contains("overlaps"));
}

fn vdb_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            vdb_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "vdb") {
            out.push(p);
        }
    }
}

/// Reads grid `g` (the `index`-th of its name) of `loc` with `reader`: a float grid as
/// one grid, a Vec3s grid as three; any other type fails the test.
fn read_any(reader: Reader, loc: &AssetLocation, g: &GridInfo, index: i32) -> Vec<RawGrid> {
    let who = format!("{loc} grid {:?} via {}", g.name, reader.name());
    let got = match g.value_type.as_str() {
        "Tree_float_5_4_3" => {
            read_float_grid_with(reader, loc, &g.name, Some(index)).map(|g| vec![g])
        }
        "Tree_vec3s_5_4_3" => {
            read_vec3s_grid_with(reader, loc, &g.name, Some(index)).map(|g| g.to_vec())
        }
        other => panic!("{who}: a {other} grid in the shared data; neither reader reads that type"),
    };
    got.unwrap_or_else(|e| panic!("{who}: {e}"))
}

/// Every grid (float and Vec3s) of every shared production file, read by both readers:
/// the same `RawGrid`s bit for bit, leaves (every value, active or not), tiles,
/// background, class and transform. The Rust reader must read every grid: a refusal
/// fails the test.
#[test]
fn real_files_cross_check() {
    let Some(dir) = common::shared_data() else {
        return;
    };
    let mut files = Vec::new();
    vdb_files(&dir, &mut files);
    assert!(!files.is_empty(), "no .vdb files under {}", dir.display());
    let (mut compared, mut rust_only) = (0, 0);
    for path in &files {
        let loc = AssetLocation::File(path.clone());
        let grids = list_grids(&loc).unwrap_or_else(|e| panic!("{e}"));
        if Reader::OpenVdb.available() {
            let ov = list_grids_with(Reader::OpenVdb, &loc).unwrap_or_else(|e| panic!("{e}"));
            // OpenVDB lists grids sorted by name, the header in file order.
            let mut a: Vec<_> = grids
                .iter()
                .map(|g| (&g.name, &g.value_type, g.active_voxels))
                .collect();
            let mut b: Vec<_> = ov
                .iter()
                .map(|g| (&g.name, &g.value_type, g.active_voxels))
                .collect();
            a.sort();
            b.sort();
            assert_eq!(a, b, "{}: grid lists differ", path.display());
        }
        for (i, g) in grids.iter().enumerate() {
            // Select by position among same-named grids, as USD's fieldIndex does.
            let index = grids[..i].iter().filter(|o| o.name == g.name).count() as i32;
            let who = format!("{} {:?} ({})", path.display(), g.name, g.value_type);
            let rs = read_any(Reader::Rust, &loc, g, index);
            for c in &rs {
                if let Some(n) = g.active_voxels {
                    assert_eq!(c.active_voxel_count(), n, "{who}: file_voxel_count");
                }
            }
            if Reader::OpenVdb.available() {
                let ov = read_any(Reader::OpenVdb, &loc, g, index);
                assert_eq!(ov.len(), rs.len());
                for (k, (o, r)) in ov.iter().zip(&rs).enumerate() {
                    assert_same_grid(o, r, &format!("{who} component {k}"));
                    // Same order too, not only the same set.
                    assert!(
                        o.leaves
                            .iter()
                            .map(|l| l.origin)
                            .eq(r.leaves.iter().map(|l| l.origin)),
                        "{who}: leaf order"
                    );
                    assert_eq!(o.tiles, r.tiles, "{who}: tile order");
                }
                compared += 1;
            } else {
                rust_only += 1;
            }
            println!(
                "{who}: {} voxels, {} leaves, {} tiles, background {:?}{}",
                rs[0].active_voxel_count(),
                rs[0].leaves.len(),
                rs[0].tiles.len(),
                rs.iter().map(|g| g.background).collect::<Vec<_>>(),
                if Reader::OpenVdb.available() {
                    ": both readers agree"
                } else {
                    ""
                }
            );
        }
    }
    println!("{compared} grids compared with OpenVDB, {rust_only} read by the Rust reader only");
    assert!(compared + rust_only > 0);
    common::data::openvdb_bridge(
        "the comparison with OpenVDB (every grid read by the Rust reader)",
    );
}

/// Renders `vdb` (its first float grid) at 32x24, 4 spp, with the reader forced
/// through `NIMBUS_VDB_READER`; returns the EXR's channels and the reader the stats
/// report.
fn render_with(reader: Reader, vdb: &Path, out_dir: &Path) -> (Vec<(String, Vec<f32>)>, String) {
    let stem = vdb.file_stem().unwrap().to_string_lossy();
    let out = out_dir.join(format!("{stem}.{}.exr", reader.name()));
    let stats = out_dir.join(format!("{stem}.{}.json", reader.name()));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .env(READER_ENV, reader.name())
        .args([
            "render",
            vdb.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "32x24",
            "--spp",
            "4",
            "--stats",
            stats.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{} via {}: {}",
        vdb.display(),
        reader.name(),
        common::cli::stderr(&o)
    );
    let used = common::cli::stats_json(&stats)["vdb_reader"]
        .as_str()
        .unwrap_or_default()
        .to_string();
    (common::cli::channels(&out), used)
}

/// Every shared VDB file rendered with each reader: bit-identical images.
#[test]
fn real_files_render_identically_with_both_readers() {
    let Some(dir) = common::shared_data() else {
        return;
    };
    let mut files = Vec::new();
    vdb_files(&dir, &mut files);
    assert!(!files.is_empty(), "no .vdb files under {}", dir.display());
    let tmp = tempfile::tempdir().unwrap();
    let compare = common::data::openvdb_bridge(
        "the comparison with OpenVDB (every file rendered with the Rust reader)",
    );
    for path in &files {
        let (rust, used) = render_with(Reader::Rust, path, tmp.path());
        assert_eq!(
            used,
            "rust",
            "{}: NIMBUS_VDB_READER=rust ignored",
            path.display()
        );
        let lit = rust
            .iter()
            .find(|c| c.0 == "A")
            .is_some_and(|a| a.1.iter().any(|&v| v > 0.0));
        assert!(lit, "{}: the render shows no volume", path.display());
        if !compare {
            continue;
        }
        let (ov, used) = render_with(Reader::OpenVdb, path, tmp.path());
        assert_eq!(
            used,
            "openvdb",
            "{}: NIMBUS_VDB_READER=openvdb ignored",
            path.display()
        );
        assert_eq!(rust.len(), ov.len(), "{}: channels", path.display());
        for ((name, a), (name_b, b)) in rust.iter().zip(&ov) {
            assert_eq!(name, name_b);
            let differ = a
                .iter()
                .zip(b)
                .filter(|(x, y)| x.to_bits() != y.to_bits())
                .count();
            assert_eq!(
                (a.len(), differ),
                (b.len(), 0),
                "{} channel {name}: pixels differ",
                path.display()
            );
        }
        println!(
            "{}: renders bit-identical ({} channels)",
            path.display(),
            rust.len()
        );
    }
}

#[test]
fn smoke_legacy_layout_matches() {
    let Some(dir) = common::shared_data() else {
        return;
    };
    let new = AssetLocation::File(dir.join("openvdb_samples/smoke.vdb"));
    let old = AssetLocation::File(dir.join("openvdb_samples/smoke1_2013.vdb"));
    for reader in readers() {
        let who = reader.name();
        let a = read_float_grid_with(reader, &new, "density", None).unwrap();
        let b = read_float_grid_with(reader, &old, "density", None).unwrap();
        assert_eq!(a.active_voxel_count(), 1_049_275, "{who}");
        assert_eq!(a.active_voxel_count(), b.active_voxel_count(), "{who}");
        assert_eq!(a.checksum(), b.checksum(), "{who}");
        assert_eq!(a.index_to_world, b.index_to_world, "{who}");
        assert_eq!(a.active_index_bounds(), Some(([1, 2, 1], [111, 223, 112])));
        assert!((a.index_to_world.x_axis.x - 0.47619).abs() < 1e-5);
        assert_eq!(a.class, "fog volume");
    }
}

/// Checks that every available reader (and the lister) rejects `loc` with an error
/// naming the file and containing `needle`.
fn assert_rejected(loc: &AssetLocation, needle: &str) {
    let file = loc.to_string();
    let e = list_grids(loc).map(|_| ()).unwrap_err().to_string();
    assert!(
        e.contains(&file) && e.contains(needle),
        "list_grids: {e:?} lacks {needle:?}"
    );
    assert!(e.len() < 2000, "message too long: {} bytes", e.len());
    for reader in readers() {
        let e = read_float_grid_with(reader, loc, "density", None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&file) && e.contains(needle),
            "{}: {e:?} lacks {needle:?}",
            reader.name()
        );
        assert!(e.len() < 2000, "message too long: {} bytes", e.len());
    }
}

fn small_file() -> Vec<u8> {
    write_float_grid_bytes(&noisy_sphere(
        [0, 0, 0],
        9,
        DMat4::from_scale(DVec3::splat(0.5)),
    ))
    .unwrap()
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let put = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        AssetLocation::File(p)
    };
    assert_rejected(&put("empty.vdb", b""), "zero bytes");
    assert_rejected(
        &put("text.vdb", b"#usda 1.0\nthis is not a volume\n"),
        "not a VDB file",
    );
    assert_rejected(&put("tiny.vdb", b"VDB"), "not a VDB file");
    assert_rejected(
        &AssetLocation::File(dir.path().join("missing.vdb")),
        "No such file",
    );

    let good = small_file();
    for cut in [8, 12, 30, 60, 100, 200, good.len() / 2, good.len() - 1] {
        assert_rejected(&put(&format!("cut{cut}.vdb"), &good[..cut]), "truncated");
    }

    // Header fields claiming enormous sizes or offsets (the layout is our writer's:
    // magic 8, version 4, library 8, offsets flag 1, uuid 36, file metadata count 4).
    let grid_count_at = 8 + 4 + 8 + 1 + 36 + 4;
    let name_len_at = grid_count_at + 4;
    let patched = |at: usize, bytes: &[u8]| {
        let mut b = good.clone();
        b[at..at + bytes.len()].copy_from_slice(bytes);
        b
    };
    assert_rejected(
        &put(
            "count.vdb",
            &patched(grid_count_at, &0x4000_0000i32.to_le_bytes()),
        ),
        "grid count",
    );
    assert_rejected(
        &put(
            "negcount.vdb",
            &patched(grid_count_at, &(-5i32).to_le_bytes()),
        ),
        "negative grid count",
    );
    assert_rejected(
        &put(
            "namelen.vdb",
            &patched(name_len_at, &0x7fff_fff0u32.to_le_bytes()),
        ),
        "claims",
    );
    let offsets_at = name_len_at + 4 + "density".len() + 4 + "Tree_float_5_4_3".len() + 4;
    assert_rejected(
        &put(
            "endpos.vdb",
            &patched(offsets_at + 16, &(6i64 << 30).to_le_bytes()),
        ),
        "offsets",
    );
    assert_rejected(
        &put("gridpos.vdb", &patched(offsets_at, &(-1i64).to_le_bytes())),
        "offsets",
    );
    // Grid metadata count right after the compression flags at the grid position.
    let grid_pos =
        i64::from_le_bytes(good[offsets_at..offsets_at + 8].try_into().unwrap()) as usize;
    assert_rejected(
        &put(
            "metacount.vdb",
            &patched(grid_pos + 4, &u32::MAX.to_le_bytes()),
        ),
        "metadata",
    );
    assert_rejected(
        &put("version.vdb", &patched(8, &999u32.to_le_bytes())),
        "version 999",
    );
    let mut magic = good.clone();
    magic[0..8].copy_from_slice(&0x2042_4456_0000_0000u64.to_le_bytes());
    assert_rejected(&put("magic.vdb", &magic), "bad magic");

    // The same checks apply to .usdz members.
    let packaged = AssetLocation::Packaged {
        package: dir.path().join("scene.usdz"),
        member: "vol/cut.vdb".into(),
        bytes: Arc::new(good[..good.len() / 3].to_vec()),
    };
    assert_rejected(&packaged, "truncated");
}

#[test]
fn wrong_grid_name_lists_available_grids() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("one.vdb");
    std::fs::write(&p, small_file()).unwrap();
    let loc = AssetLocation::File(p);
    for reader in readers() {
        let e = read_float_grid_with(reader, &loc, "temperature", None).unwrap_err();
        assert!(matches!(e, VdbError::GridNotFound { .. }));
        let e = e.to_string();
        assert!(
            e.contains("one.vdb")
                && e.contains("\"temperature\"")
                && e.contains("available grids: \"density\""),
            "{e}"
        );
        let e = read_float_grid_with(reader, &loc, "density", Some(1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("index 1"), "{e}");
        let e = read_float_grid_with(reader, &loc, "density", Some(-1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("index -1"), "{e}");
    }
    if !Reader::OpenVdb.available() {
        let e = read_float_grid_with(Reader::OpenVdb, &loc, "density", None).unwrap_err();
        assert!(matches!(e, VdbError::Unsupported { .. }));
        assert!(e.to_string().contains("libopenvdb-dev"), "{e}");
        assert_eq!(active_reader(), Reader::Rust);
    } else {
        assert_eq!(active_reader(), Reader::OpenVdb);
    }
    // The default reader finds it by name.
    assert!(read_float_grid(&loc, "density", None).is_ok());
    println!("default reader: {}", active_reader().name());
}

#[test]
fn vec3s_grid_is_a_type_error() {
    // Same-length type name, so the rest of the file stays consistent.
    let mut bytes = small_file();
    let at = bytes
        .windows(16)
        .position(|w| w == b"Tree_float_5_4_3")
        .unwrap();
    bytes[at..at + 16].copy_from_slice(b"Tree_vec3s_5_4_3");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("vel.vdb");
    std::fs::write(&p, &bytes).unwrap();
    let loc = AssetLocation::File(p);
    assert_eq!(list_grids(&loc).unwrap()[0].value_type, "Tree_vec3s_5_4_3");
    for reader in readers() {
        let e = read_float_grid_with(reader, &loc, "density", None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vel.vdb") && e.contains("grid \"density\" is Vec3s, expected float"),
            "{e}"
        );
    }
}

#[test]
fn real_file_truncated_and_corrupted() {
    let Some(src) = common::shared_file("openusd_blender_smoke/densityAndHeat.vdb") else {
        return;
    };
    let good = std::fs::read(&src).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    for cut in [0, 7, 50, 300, good.len() / 2, good.len() - 1] {
        let p = tmp.path().join(format!("cut{cut}.vdb"));
        std::fs::write(&p, &good[..cut]).unwrap();
        let loc = AssetLocation::File(p);
        for reader in readers() {
            let e = read_float_grid_with(reader, &loc, "density", None)
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("cut{cut}.vdb")), "{e}");
        }
    }
}

/// Corrupts copies of a file by flipping random bits (xorshift64, fixed seed: the same
/// copies every run).
struct BitFlips(u64);

impl BitFlips {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// `good` with `n` bits flipped at random places.
    fn flipped(&mut self, good: &[u8], n: usize) -> Vec<u8> {
        let mut b = good.to_vec();
        for _ in 0..n {
            let at = (self.next() % b.len() as u64) as usize;
            b[at] ^= 1 << (self.next() % 8);
        }
        b
    }
}

/// Byte flips all over a small uncompressed file: every outcome must be an `Ok` or an
/// `Err`, never a panic or an abort.
#[test]
fn corrupted_bytes_never_crash() {
    let good = small_file();
    let dir = tempfile::tempdir().unwrap();
    let mut flips = BitFlips(0x1234_5678_9abc_def0u64);
    let (mut ok, mut err) = (0, 0);
    for i in 0..150 {
        let b = flips.flipped(&good, 1 + i % 4);
        let p = dir.path().join(format!("flip{i}.vdb"));
        std::fs::write(&p, &b).unwrap();
        let loc = AssetLocation::File(p);
        for reader in readers() {
            match read_float_grid_with(reader, &loc, "", None) {
                Ok(_) => ok += 1,
                Err(e) => {
                    assert!(e.to_string().contains(&format!("flip{i}.vdb")), "{e}");
                    assert!(e.to_string().len() < 2000);
                    err += 1;
                }
            }
        }
    }
    println!("corrupted files: {ok} read, {err} rejected");
}

/// Replaces the writer's ScaleTranslateMap with map `name` and raw `payload`, fixing
/// the descriptor offsets (single-grid files only).
fn with_map(bytes: &[u8], name: &str, payload: &[u8]) -> Vec<u8> {
    let old = b"UniformScaleTranslateMap";
    let at = bytes.windows(old.len()).position(|w| w == old).unwrap() - 4;
    let old_len = 4 + old.len() + 6 * 24;
    let mut map = Vec::new();
    map.extend_from_slice(&(name.len() as u32).to_le_bytes());
    map.extend_from_slice(name.as_bytes());
    map.extend_from_slice(payload);
    let delta = map.len() as i64 - old_len as i64;
    let mut out = bytes[..at].to_vec();
    out.extend_from_slice(&map);
    out.extend_from_slice(&bytes[at + old_len..]);
    // Block and end offsets follow the grid offset in the single descriptor.
    let desc = 8 + 4 + 8 + 1 + 36 + 4 + 4;
    let offsets = desc + 4 + "density".len() + 4 + "Tree_float_5_4_3".len() + 4;
    for k in 1..3 {
        let p = offsets + 8 * k;
        let v = i64::from_le_bytes(out[p..p + 8].try_into().unwrap()) + delta;
        out[p..p + 8].copy_from_slice(&v.to_le_bytes());
    }
    out
}

/// An AffineMap as OpenVDB writes it: the row-vector matrix, row-major, which is
/// the column-major storage of our column-vector matrix.
fn with_affine_map(bytes: &[u8], column_vector: DMat4) -> Vec<u8> {
    let payload: Vec<u8> = column_vector
        .to_cols_array()
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    with_map(bytes, "AffineMap", &payload)
}

#[test]
fn frustum_transform_is_refused_by_both() {
    let grid = noisy_sphere([0, 0, 0], 9, DMat4::IDENTITY);
    let bytes = with_map(
        &write_float_grid_bytes(&grid).unwrap(),
        "NonlinearFrustumMap",
        &[0u8; 200],
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("frustum.vdb");
    std::fs::write(&p, &bytes).unwrap();
    let loc = AssetLocation::File(p);
    for reader in readers() {
        let e = read_float_grid_with(reader, &loc, "density", None).unwrap_err();
        assert!(matches!(e, VdbError::Unsupported { .. }), "{e}");
        let e = e.to_string();
        assert!(
            e.contains("frustum.vdb") && e.contains("NonlinearFrustumMap transform"),
            "{e}"
        );
    }
}

/// An AffineMap (rotation, non-uniform scale, translation) reads through both readers
/// with the same matrix and voxels.
#[test]
fn affine_transform_both_readers_read() {
    let grid = noisy_sphere([0, 0, 0], 9, DMat4::IDENTITY);
    let affine = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0))
        * DMat4::from_rotation_z(0.5)
        * DMat4::from_scale(DVec3::new(0.1, 0.2, 0.3));
    let bytes = with_affine_map(&write_float_grid_bytes(&grid).unwrap(), affine);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("affine.vdb");
    std::fs::write(&p, &bytes).unwrap();
    let loc = AssetLocation::File(p);
    let mut want = grid.clone();
    want.index_to_world = affine;
    for reader in readers() {
        let got = read_float_grid_with(reader, &loc, "density", None)
            .unwrap_or_else(|e| panic!("{}: {e}", reader.name()));
        assert_eq!(got.checksum(), grid.checksum());
        // OpenVDB's row-vector matrix becomes our column-vector one.
        assert!(
            got.index_to_world.abs_diff_eq(affine, 1e-12),
            "{}: {:?}",
            reader.name(),
            got.index_to_world
        );
        let w = got
            .index_to_world
            .transform_point3(DVec3::new(10.0, 0.0, 0.0));
        let want_w = DVec3::new(1.0 + 0.5f64.cos(), 2.0 + 0.5f64.sin(), 3.0);
        assert!(w.abs_diff_eq(want_w, 1e-12), "{w:?}");
        want.index_to_world = got.index_to_world;
        assert_same_grid(&want, &got, reader.name());
    }
}

#[test]
fn multi_grid_file_with_duplicate_names() {
    let m = scale_translate(DVec3::splat(0.25), DVec3::new(-1.0, 0.0, 1.0));
    let a = noisy_sphere([0, 0, 0], 6, m);
    let mut b = noisy_sphere([30, 0, 0], 8, m);
    b.name = "temperature".into();
    let mut c = noisy_sphere([-20, 10, 0], 7, m);
    c.class = "unknown".into();
    let mut empty = noisy_sphere([0, 0, 0], 3, m);
    empty.leaves.clear();
    empty.tiles.clear();
    empty.name = "empty".into();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("multi.vdb");
    write_float_grids(&p, &[a.clone(), b.clone(), c.clone(), empty.clone()]).unwrap();
    let loc = AssetLocation::File(p);
    let names: Vec<String> = list_grids(&loc)
        .unwrap()
        .into_iter()
        .map(|g| g.name)
        .collect();
    assert_eq!(names, ["density", "temperature", "density", "empty"]);
    for reader in readers() {
        let who = reader.name();
        let get = |name: &str, index: Option<i32>| {
            read_float_grid_with(reader, &loc, name, index).unwrap_or_else(|e| panic!("{who}: {e}"))
        };
        assert_same_grid(&a, &get("density", None), who);
        assert_same_grid(&a, &get("density", Some(0)), who);
        assert_same_grid(&c, &get("density", Some(1)), who);
        assert_same_grid(&b, &get("temperature", None), who);
        assert_same_grid(&c, &get("", Some(2)), who);
        let e = get("empty", None);
        assert_eq!(
            (e.leaves.len(), e.tiles.len(), e.active_voxel_count()),
            (0, 0, 0)
        );
        let err = read_float_grid_with(reader, &loc, "density", Some(2))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("index 2 (of 2)") && err.contains("\"temperature\""),
            "{err}"
        );
    }
    if Reader::OpenVdb.available() {
        let mut ov: Vec<String> = list_grids_with(Reader::OpenVdb, &loc)
            .unwrap()
            .into_iter()
            .map(|g| g.name)
            .collect();
        ov.sort();
        assert_eq!(ov, ["density", "density", "empty", "temperature"]);
    }
}

/// Byte flips in a real blosc-compressed file both readers can read: errors, never
/// a crash (c-blosc trusts the sizes in its headers, so validation checks them).
#[test]
fn corrupted_real_file_never_crashes() {
    let Some(src) = common::shared_file("openusd_blender_smoke/densityAndHeat.vdb") else {
        return;
    };
    let good = std::fs::read(src).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut flips = BitFlips(0x0dd_ba11_cafe_f00du64);
    let (mut ok, mut err) = (0, 0);
    for i in 0..200 {
        let b = flips.flipped(&good, 1 + i % 3);
        let p = tmp.path().join(format!("flip{i}.vdb"));
        std::fs::write(&p, &b).unwrap();
        let loc = AssetLocation::File(p);
        for reader in readers() {
            for name in ["density", "heat"] {
                match read_float_grid_with(reader, &loc, name, None) {
                    Ok(_) => ok += 1,
                    Err(e) => {
                        let e = e.to_string();
                        assert!(e.contains(&format!("flip{i}.vdb")) && e.len() < 2000, "{e}");
                        err += 1;
                    }
                }
            }
        }
    }
    println!("corrupted real files: {ok} read, {err} rejected");
}

/// The value `tests/fixtures/make_inactive_vdb.cc` gives voxel `off` of leaf `leaf`
/// (component `c` of a Vec3s grid, whose values are (v, −v, 2v)), and whether it is
/// active.
fn inactive_fixture_value(leaf: usize, off: usize, c: usize, bg: f32) -> (f32, bool) {
    let vec = |v: f32| [v, -v, 2.0 * v][c];
    if off == 0 || leaf == 7 {
        return (vec(0.01 * off as f32 + leaf as f32), true);
    }
    let (three, seven) = (vec(3.0), vec(7.0));
    let v = match leaf {
        0 => bg,
        1 => -bg,
        2 => three,
        3 if off % 3 == 0 => -bg,
        3 => bg,
        4 if off % 5 == 0 => three,
        4 => bg,
        5 if off % 2 == 0 => three,
        5 => seven,
        _ => [bg, three, seven][off % 3],
    };
    (v, false)
}

/// Files OpenVDB itself wrote (`tests/fixtures/make_inactive_vdb.cc`) whose nodes need
/// every kind of value record (metadata 0 to 6), with non-zero backgrounds, float and
/// Vec3s, full and half precision, under active-mask-only, zlib and blosc compression,
/// with an affine transform: the Rust reader restores every inactive value the
/// generator wrote, and returns OpenVDB's grids bit for bit.
#[test]
fn openvdb_written_inactive_values_both_readers() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    for file in [
        "inactive_mask.vdb",
        "inactive_zip.vdb",
        "inactive_blosc.vdb",
    ] {
        let loc = AssetLocation::File(dir.join(file));
        for name in ["f", "f_half", "v", "v_half"] {
            let who = format!("{file} {name}");
            let read = |reader: Reader| -> Vec<RawGrid> {
                if name.starts_with('f') {
                    read_float_grid_with(reader, &loc, name, None).map(|g| vec![g])
                } else {
                    read_vec3s_grid_with(reader, &loc, name, None).map(|g| g.to_vec())
                }
                .unwrap_or_else(|e| panic!("{who} via {}: {e}", reader.name()))
            };
            let rs = read(Reader::Rust);
            // Half floats keep 11 significant bits: relative error at most 2^-11.
            let tol = if name.ends_with("half") {
                1.0 / 2048.0
            } else {
                0.0
            };
            for (c, g) in rs.iter().enumerate() {
                let bg = [0.5f32, -0.25, 2.0][c];
                assert_eq!(g.background, bg, "{who}");
                assert_eq!(g.class, "fog volume");
                assert!(g.index_to_world.x_axis.y.abs() > 0.01, "{who}: not rotated");
                assert_eq!(g.leaves.len(), 8, "{who}");
                for leaf in &g.leaves {
                    let l = (leaf.origin[0] / 8) as usize;
                    assert_eq!(leaf.origin, [8 * l as i32, 0, 0]);
                    for off in 0..512 {
                        let (want, active) = inactive_fixture_value(l, off, c, bg);
                        assert_eq!(leaf.active[off / 64] >> (off % 64) & 1 == 1, active);
                        let got = leaf.values[off];
                        assert!(
                            (got - want).abs() <= tol * want.abs(),
                            "{who}[{c}] leaf {l} voxel {off}: {got} vs {want}"
                        );
                    }
                }
                let vec = |v: f32| [v, -v, 2.0 * v][c];
                let mut tiles = g.tiles.clone();
                tiles.sort_by_key(|t| (t.dim, t.origin));
                let want = [
                    ([0, 64, 0], 8, vec(0.75), true),
                    ([8, 64, 0], 8, vec(3.0), false),
                    ([0, 1024, 0], 128, vec(0.125), true),
                    ([8192, 0, 0], 4096, vec(2.0), true),
                ]
                .map(|(origin, dim, value, active)| RawTile {
                    origin,
                    dim,
                    value,
                    active,
                });
                assert_eq!(tiles, want, "{who}[{c}]");
            }
            if Reader::OpenVdb.available() {
                let ov = read(Reader::OpenVdb);
                for (k, (o, r)) in ov.iter().zip(&rs).enumerate() {
                    assert_same_grid(o, r, &format!("{who} component {k}"));
                    assert_eq!(o.tiles, r.tiles, "{who}: tile order");
                }
            }
        }
    }
    common::data::openvdb_bridge("the comparison with OpenVDB (the generator's values checked)");
}

/// Byte flips in the OpenVDB-written fixtures (every value-record kind; mask-only, zlib
/// and blosc chunks; float and Vec3s; half floats): the Rust reader answers each with
/// grids or an error naming the file, never a panic or an abort, including where a
/// flip lands inside compressed data that validation does not decode.
#[test]
fn corrupted_fixtures_never_crash_the_rust_reader() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let tmp = tempfile::tempdir().unwrap();
    let mut flips = BitFlips(0x5eed_0f_f1a5_u64);
    let (mut ok, mut err) = (0, 0);
    for file in [
        "inactive_mask.vdb",
        "inactive_zip.vdb",
        "inactive_blosc.vdb",
    ] {
        let good = std::fs::read(dir.join(file)).unwrap();
        for i in 0..100 {
            let b = flips.flipped(&good, 1 + i % 3);
            let name = format!("flip{i}_{file}");
            let p = tmp.path().join(&name);
            std::fs::write(&p, &b).unwrap();
            let loc = AssetLocation::File(p);
            for grid in ["f", "f_half", "v", "v_half"] {
                let r = if grid.starts_with('f') {
                    read_float_grid_with(Reader::Rust, &loc, grid, None).map(|_| ())
                } else {
                    read_vec3s_grid_with(Reader::Rust, &loc, grid, None).map(|_| ())
                };
                match r {
                    Ok(()) => ok += 1,
                    Err(e) => {
                        let e = e.to_string();
                        assert!(e.contains(&name) && e.len() < 2000, "{e}");
                        err += 1;
                    }
                }
            }
        }
    }
    println!("corrupted fixtures: {ok} read, {err} rejected");
}
