//! `nimbus bench cumulus` and `nimbus bench tables` (the supplement's Tables 1 and 2):
//! the production cumulus is the example cloud's field (at the example's resolution
//! it is the example's grid, voxel for voxel), and the tables' counts are those of
//! plain renders with each tracker and depth, timed or not.

use nimbus::bench::cumulus::{self, cumulus_grid, CumulusSpec};
use nimbus::bench::octree_tables::{self, tracker_settings, Shadows, TablesConfig, TRACKERS};
use nimbus::render::analysis::CodePaths;
use nimbus::render::session::{Overrides, Session};
use nimbus::volume::asset::AssetLocation;
use nimbus::volume::grid::BRICK;
use nimbus::volume::vdb;
use std::collections::HashMap;

mod common;

/// At 128 voxels across, the cropped production grid holds exactly the example
/// cloud's active voxels with the same values (same voxel lattice, same world
/// positions): the crop box and the lumps' early exit lose nothing.
#[test]
fn cumulus_at_the_example_resolution_is_the_example_cloud() {
    let example = vdb::read_float_grid(
        &AssetLocation::File(common::repo().join("scenes/cloud/cloud.vdb")),
        "density",
        None,
    )
    .unwrap();
    let ours = cumulus_grid(128);
    // World position of a voxel (the two grids differ by an integer index offset).
    let world = |g: &nimbus::volume::grid::RawGrid, ijk: [i32; 3]| {
        let p = g.index_to_world.transform_point3(glam::DVec3::new(
            ijk[0] as f64,
            ijk[1] as f64,
            ijk[2] as f64,
        ));
        // Voxel centres lie on the lattice -1 + (i + 1/2)/64: exact to rounding.
        [p.x, p.y, p.z].map(|c| ((c + 1.0) * 64.0 - 0.5).round() as i32)
    };
    let voxels = |g: &nimbus::volume::grid::RawGrid| {
        let mut m = HashMap::new();
        for leaf in &g.leaves {
            for off in 0..(BRICK * BRICK * BRICK) as usize {
                if leaf.active[off / 64] >> (off % 64) & 1 == 1 {
                    let ijk = [
                        leaf.origin[0] + (off >> 6) as i32,
                        leaf.origin[1] + ((off >> 3) & 7) as i32,
                        leaf.origin[2] + (off & 7) as i32,
                    ];
                    m.insert(world(g, ijk), leaf.values[off].to_bits());
                }
            }
        }
        m
    };
    let (a, b) = (voxels(&example), voxels(&ours));
    assert_eq!(a.len(), 277_968, "the example cloud's active voxels");
    assert_eq!(a, b);
}

/// The thick stage's density scale gives the asked-for mean free path at density 1,
/// and the thin one is `thin_factor` times thinner; the files are written.
#[test]
fn cumulus_writes_a_thick_and_a_thin_stage() {
    let dir = tempfile::tempdir().unwrap();
    let spec = CumulusSpec {
        resolution: 48,
        mean_free_path: 2.0,
        thin_factor: 10.0,
    };
    let f = cumulus::write(dir.path(), &spec).unwrap();
    assert!(
        f.active_voxels > 10_000,
        "{} active voxels",
        f.active_voxels
    );
    // σt = 1 per unit density: the mean free path at density 1 is 1/scale world units.
    let mfp_voxels = 1.0 / spec.thick_density_scale() / spec.voxel_size();
    assert!((mfp_voxels - 2.0).abs() < 1e-12);
    assert!((spec.thick_density_scale() / spec.thin_density_scale() - 10.0).abs() < 1e-12);
    for stage in [&f.thick, &f.thin] {
        let s = Session::open(
            stage,
            &Overrides {
                res: Some((8, 6)),
                spp: Some(1),
                ..Overrides::default()
            },
        )
        .unwrap();
        assert_eq!(s.media().len(), 1);
        assert_eq!(s.media()[0].density.active_voxels, f.active_voxels);
    }
    let bad = CumulusSpec {
        resolution: 8,
        ..spec
    };
    let err = cumulus::write(dir.path(), &bad).unwrap_err().to_string();
    assert!(err.contains("--resolution"), "{err}");
}

/// The tables' counts for each depth and tracker are those of a session opened with
/// that tracker and depth (as `nimbus render --octree-depth D --tracker T
/// --octree-prune P` renders), whether the bench's timers were on or not, in every
/// round; so are the images.
#[test]
fn tables_count_what_plain_renders_count() {
    let dir = tempfile::tempdir().unwrap();
    let spec = CumulusSpec {
        resolution: 48,
        ..CumulusSpec::default()
    };
    let f = cumulus::write(dir.path(), &spec).unwrap();
    // Pruned and not; each tracker's ratio-type shadow rays, and its own free paths.
    for (prune, shadows) in [
        (0.0, Shadows::Ratio),
        (1.0, Shadows::Ratio),
        (0.0, Shadows::Tracking),
    ] {
        let o = Overrides {
            res: Some((12, 9)),
            spp: Some(2),
            octree_depth: Some(1),
            octree_prune: Some(prune),
            threads: Some(1),
            ..Overrides::default()
        };
        let mut session = Session::open(&f.thick, &o).unwrap();
        let pool = session.pool(1).unwrap();
        let config = TablesConfig {
            depths: vec![1, 4, 6],
            rounds: 2,
            timed: true,
            shadows,
        };
        let tables = octree_tables::measure(&mut session, &pool, &config, |_| {}).unwrap();
        assert_eq!(tables.rows.len(), 6);
        assert_eq!(
            tables.runs.len(),
            6 * 2 * 2,
            "rounds × timed/untimed per row"
        );
        for &depth in &config.depths {
            for tracker in TRACKERS {
                let row = tables.row(depth, tracker).unwrap();
                let settings = tracker_settings(tracker, shadows);
                let plain = Session::open(
                    &f.thick,
                    &Overrides {
                        octree_depth: Some(depth),
                        tracker: Some(tracker.name().into()),
                        transmittance: Some(settings.transmittance),
                        ..o.clone()
                    },
                )
                .unwrap();
                let film = common::render_job(&plain, &plain.job_with(CodePaths::default()), None);
                let c = film.totals().0;
                let r = &row.counts;
                assert_eq!(
                    (
                        c.density_lookups,
                        c.cells_visited,
                        c.residual_lookups,
                        c.real_collisions
                    ),
                    (
                        r.density_lookups,
                        r.cells_visited,
                        r.residual_lookups,
                        r.real_collisions
                    ),
                    "prune {prune}, {shadows:?} shadows, depth {depth}, {}",
                    tracker.name()
                );
                let runs: Vec<_> = tables
                    .runs
                    .iter()
                    .filter(|x| x.depth == depth && x.tracker == tracker)
                    .collect();
                assert_eq!(runs.iter().filter(|x| x.timed).count(), 2);
                for x in &runs {
                    assert_eq!(x.counts.density_lookups, c.density_lookups);
                    assert_eq!(x.counts.cells_visited, c.cells_visited);
                    assert_eq!(x.image_digest, runs[0].image_digest);
                    // Timed runs split their CPU seconds; untimed ones do not.
                    assert_eq!(x.times.is_some(), x.timed);
                    if let (Some(t), Some(out)) = (x.times, x.outside_seconds) {
                        let sum =
                            t.lookup_seconds + t.traversal_seconds + t.other_tracker_seconds + out;
                        assert!((sum - x.cpu_seconds).abs() < 1e-9 * x.cpu_seconds.max(1.0));
                    }
                }
            }
        }
        // Decomposition makes residual lookups only; delta none.
        let d = tables.row(6, TRACKERS[0]).unwrap();
        let x = tables.row(6, TRACKERS[1]).unwrap();
        assert_eq!(d.counts.residual_lookups, 0);
        assert_eq!(x.counts.residual_lookups, x.counts.density_lookups);
        assert!(tables.csv().lines().count() == 1 + 6 + 3);
        assert!(tables.runs_csv().lines().count() == 1 + 24);
    }
}
