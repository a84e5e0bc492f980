//! End-to-end tests of `nimbus render` on a stage with render products: each product
//! is written with its own render vars.

mod common;

use common::cli::{assert_clean_error, channel, channels, cloud_stage_with, nimbus, root, stderr};
use std::path::{Path, PathBuf};

/// A text attribute of an EXR's first header (e.g. `nimbus:scheme`).
fn exr_text_attribute(path: &Path, key: &str) -> Option<String> {
    use exr::meta::attribute::{AttributeValue, Text};
    let meta = exr::meta::MetaData::read_from_file(path, false).expect("EXR header");
    let h = meta.headers.first()?;
    let key = Text::from(key);
    match h.own_attributes.other.get(&key)? {
        AttributeValue::Text(t) => Some(t.to_string()),
        _ => None,
    }
}

/// The chromatic scene with two RenderProducts at `beauty` and `counters`: the first
/// with color and lookups, the second with alpha, real_collisions and variance.
fn two_product_stage(dir: &Path, beauty: &str, counters: &str) -> PathBuf {
    std::fs::copy(
        root().join("scenes/chromatic/chromatic.vdb"),
        dir.join("chromatic.vdb"),
    )
    .unwrap();
    let text = std::fs::read_to_string(root().join("scenes/chromatic/chromatic.usda"))
        .unwrap()
        .replace(
            "rel products = </Render/Product>",
            "rel products = [</Render/Product>, </Render/Counters>]",
        )
        .replace(
            "uniform token productName = \"chromatic.exr\"",
            &format!("uniform token productName = \"{beauty}\""),
        )
        .replace(
            "    def Scope \"Vars\"\n",
            &format!(
                "    def RenderProduct \"Counters\"
    {{
        uniform token productName = \"{counters}\"
        rel orderedVars = [</Render/Extra/alpha>, </Render/Extra/real>, </Render/Extra/variance>]
    }}

    def Scope \"Extra\"
    {{
        def RenderVar \"alpha\" {{ uniform string sourceName = \"alpha\" }}
        def RenderVar \"real\" {{ uniform string sourceName = \"real_collisions\" }}
        def RenderVar \"variance\" {{ uniform string sourceName = \"variance\" }}
    }}

    def Scope \"Vars\"
"
            ),
        );
    let path = dir.join("products.usda");
    std::fs::write(&path, text).unwrap();
    path
}

/// Every RenderVar of every RenderProduct is a channel of that product's EXR (plus R, G,
/// B, A in each); `-o` replaces the first product's path only; the header records the
/// settings; products colliding on one path, unknown source names and a stage without
/// products or -o are clear errors.
#[test]
fn render_products_each_get_their_vars() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let beauty = d.join("beauty.exr");
    let counters = d.join("counters.exr");
    let stage = two_product_stage(d, beauty.to_str().unwrap(), counters.to_str().unwrap());
    let s = stage.to_str().unwrap();
    let base = ["render", s, "--res", "8x6", "--spp", "2"];
    let o = nimbus(&base);
    assert!(o.status.success(), "{}", stderr(&o));
    let names = |p: &Path| -> Vec<String> {
        let mut n: Vec<String> = channels(p).into_iter().map(|c| c.0).collect();
        n.sort();
        n
    };
    assert_eq!(names(&beauty), ["A", "B", "G", "R", "lookups"]);
    assert_eq!(
        names(&counters),
        ["A", "B", "G", "R", "real_collisions", "variance"]
    );
    // One film: the channels both products share are the same pixels.
    let (b, c) = (channels(&beauty), channels(&counters));
    for ch in ["R", "G", "B", "A"] {
        assert_eq!(channel(&b, ch), channel(&c, ch), "{ch}");
    }
    assert!(channel(&c, "real_collisions").iter().any(|&v| v > 0.0));
    assert_eq!(
        exr_text_attribute(&beauty, "nimbus:renderProduct").as_deref(),
        Some("/Render/Product")
    );
    assert_eq!(
        exr_text_attribute(&counters, "nimbus:renderProduct").as_deref(),
        Some("/Render/Counters")
    );
    for (key, want) in [
        // `auto` (the default) picks ratio-select: the medium is chromatic and
        // heterogeneous, without emission.
        ("nimbus:tracker", "ratio-select"),
        ("nimbus:scheme", "hist-avg"),
        ("nimbus:transmittance", "ratio"),
        ("nimbus:version", env!("CARGO_PKG_VERSION")),
        ("nimbus:stage", s),
    ] {
        assert_eq!(
            exr_text_attribute(&beauty, key).as_deref(),
            Some(want),
            "{key}"
        );
    }
    assert_eq!(
        nimbus::output::exr::read_i32_attribute(&beauty, "nimbus:spp").unwrap(),
        Some(2)
    );

    // -o replaces the first product's path; the second product keeps its own.
    std::fs::remove_file(&counters).unwrap();
    let over = d.join("over.exr");
    let mut args = base.to_vec();
    args.extend(["-o", over.to_str().unwrap(), "--aovs", "null_collisions"]);
    let o = nimbus(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        names(&over),
        ["A", "B", "G", "R", "lookups", "null_collisions"]
    );
    assert_eq!(channel(&channels(&over), "R"), channel(&b, "R"));
    assert!(counters.is_file(), "second product written");

    // Two products on one file.
    let same = two_product_stage(d, beauty.to_str().unwrap(), beauty.to_str().unwrap());
    assert_clean_error(
        &nimbus(&["render", same.to_str().unwrap(), "--res", "8x6"]),
        "both write",
    );
    // No products and no -o.
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("cloud.vdb")).unwrap();
    let plain = cloud_stage_with(d, "asset filePath = @./cloud.vdb@", "density", "");
    let text = std::fs::read_to_string(&plain)
        .unwrap()
        .replace("rel products = </Render/Product>", "");
    std::fs::write(&plain, text).unwrap();
    assert_clean_error(
        &nimbus(&["render", plain.to_str().unwrap(), "--res", "8x6"]),
        "give one with -o",
    );
    // An unknown source name lists the known ones.
    let text = std::fs::read_to_string(&stage)
        .unwrap()
        .replace("\"real_collisions\"", "\"depth\"");
    std::fs::write(&stage, text).unwrap();
    let o = nimbus(&base);
    assert_clean_error(&o, "/Render/Extra/real: sourceName \"depth\"");
    assert!(
        stderr(&o).contains("known: color, alpha, R, G, B, A, lookups"),
        "{}",
        stderr(&o)
    );
}
