//! USD loading tests: stages authored by Pixar's USD (`tests/fixtures/make_stages.py`)
//! are loaded with `nimbus::scene::load_stage` and compared against the values pxr
//! computes for them. Bad-input tests need no pxr.

mod common;

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};
use nimbus::scene::{load_stage, Field, LoadOptions, Scene, SceneError};
use nimbus::volume::asset::AssetLocation;
use serde_json::Value;

const REL_TOL: f64 = 1e-9;

/// Runs the fixture generator into a fresh temp dir; `None` (with a message)
/// when Pixar's USD is not installed.
fn generate_fixtures() -> Option<(tempfile::TempDir, Value)> {
    common::pxr_fixtures("make_stages.py", &["pxr"], common::data::SETUP_PYTHON, true)
}

// ----- comparison helpers -----------------------------------------------------------------

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

fn num(v: &Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("expected a number, got {v}"))
}

fn assert_num(what: &str, actual: f64, expected: &Value, tol: f64) {
    let e = num(expected);
    assert!(close(actual, e, tol), "{what}: got {actual}, pxr says {e}");
}

fn assert_vec(what: &str, actual: &[f64], expected: &Value, tol: f64) {
    let e: Vec<f64> = expected
        .as_array()
        .expect("array")
        .iter()
        .map(num)
        .collect();
    assert_eq!(actual.len(), e.len(), "{what}: length");
    for (a, b) in actual.iter().zip(&e) {
        assert!(close(*a, *b, tol), "{what}: got {actual:?}, pxr says {e:?}");
    }
}

/// `expected` is pxr's row-major, row-vector matrix; `probe` is pxr's transform of
/// the point (1,2,3). Both the elements and the convention are checked.
fn assert_transform(what: &str, m: &DMat4, expected: &Value, probe: &Value) {
    let rows = expected.as_array().expect("matrix rows");
    for (r, row) in rows.iter().enumerate() {
        for (c, e) in row.as_array().expect("row").iter().enumerate() {
            // Column-vector matrix: element (row c, column r) is pxr's (r, c).
            let actual = m.col(r)[c];
            assert!(
                close(actual, num(e), REL_TOL),
                "{what}[{r}][{c}]: got {actual}, pxr says {e}\n{m:?}"
            );
        }
    }
    let p = m.transform_point3(DVec3::new(1.0, 2.0, 3.0));
    assert_vec(&format!("{what} * (1,2,3)"), &p.to_array(), probe, REL_TOL);
}

fn f32_tol() -> f64 {
    // Values authored as float in USD; pxr reports them widened to double exactly
    // as we do, but keep a float-sized margin for anything computed.
    1e-6
}

fn assert_field(what: &str, field: &Field, expected: &Value) {
    assert_eq!(
        field.prim_path,
        expected["prim_path"].as_str().unwrap(),
        "{what} prim"
    );
    assert_eq!(
        field.field_name,
        expected["field_name"].as_str().unwrap(),
        "{what} fieldName"
    );
    assert_eq!(
        field.field_index,
        expected["field_index"].as_i64().map(|i| i as i32),
        "{what} fieldIndex"
    );
    let file = &expected["file"];
    match &field.file {
        AssetLocation::File(path) => {
            let e = file["file"]
                .as_str()
                .unwrap_or_else(|| panic!("{what}: pxr has {file}, we have {path:?}"));
            assert_same_file(what, path, Path::new(e));
        }
        AssetLocation::Packaged {
            package,
            member,
            bytes,
        } => {
            let e = file["package"]
                .as_str()
                .unwrap_or_else(|| panic!("{what}: pxr has {file}, we have a package"));
            assert_same_file(what, package, Path::new(e));
            assert_eq!(member, file["member"].as_str().unwrap(), "{what} member");
            assert_eq!(
                bytes.as_slice(),
                file["bytes"].as_str().unwrap().as_bytes(),
                "{what} bytes"
            );
        }
    }
}

fn assert_same_file(what: &str, actual: &Path, expected: &Path) {
    let canon = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    assert_eq!(canon(actual), canon(expected), "{what}: file");
}

/// RenderProducts in the settings' `products` order, each with its `orderedVars`.
fn assert_products(actual: &[nimbus::scene::RenderProduct], expected: &Value) {
    let products = expected.as_array().unwrap();
    assert_eq!(actual.len(), products.len(), "products");
    for (p, e) in actual.iter().zip(products) {
        assert_eq!(p.prim_path, e["prim_path"].as_str().unwrap());
        assert_eq!(p.product_name.as_deref(), e["product_name"].as_str());
        let vars = e["vars"].as_array().unwrap();
        assert_eq!(p.vars.len(), vars.len());
        for (v, ev) in p.vars.iter().zip(vars) {
            assert_eq!(v.prim_path, ev["prim_path"].as_str().unwrap());
            assert_eq!(v.source_name, ev["source_name"].as_str().unwrap());
            assert_eq!(v.data_type, ev["data_type"].as_str().unwrap());
        }
    }
}

/// Volumes (visible, active only, in namespace order): transforms, fields (resolved
/// files or package members with their bytes) and the volume parameters.
fn assert_volumes(scene: &Scene, expected: &Value) {
    let tol = f32_tol();
    let vols = expected["volumes"].as_array().unwrap();
    let names: Vec<&str> = scene.volumes.iter().map(|v| v.prim_path.as_str()).collect();
    let expected_names: Vec<&str> = vols
        .iter()
        .map(|v| v["prim_path"].as_str().unwrap())
        .collect();
    assert_eq!(names, expected_names, "volumes");
    for (v, e) in scene.volumes.iter().zip(vols) {
        let what = v.prim_path.as_str();
        assert_transform(what, &v.volume_to_world, &e["world"], &e["probe"]);
        assert_field(
            &format!("{what} density"),
            v.shape.field().expect("a density field"),
            &e["density"],
        );
        let fields = e["fields"].as_object().unwrap();
        let names: Vec<&String> = v.fields.iter().map(|(n, _)| n).collect();
        assert_eq!(
            names,
            fields.keys().collect::<Vec<_>>(),
            "{what} field names"
        );
        for (name, field) in &v.fields {
            assert_field(&format!("{what} field:{name}"), field, &fields[name]);
        }
        assert_num("densityScale", v.density_scale, &e["density_scale"], tol);
        assert_vec("absorption", &v.absorption, &e["absorption"], tol);
        assert_vec("scattering", &v.scattering, &e["scattering"], tol);
        assert_num("anisotropy", v.anisotropy, &e["anisotropy"], tol);
        assert_emission(what, &v.emission, &e["emission"]);
        match (&v.albedo, e["albedo"].as_array()) {
            (None, None) => {}
            (Some((name, f)), Some(pair)) => {
                assert_eq!(name, pair[0].as_str().unwrap(), "{what} albedoField");
                assert_field(&format!("{what} albedoField"), f, &pair[1]);
            }
            (a, _) => panic!("{what} albedoField: got {a:?}, pxr says {}", e["albedo"]),
        }
    }
}

/// The emission configuration (issue 8): the named fields and the parameters pxr
/// resolves (authored, time-sampled or schema fallbacks).
fn assert_emission(what: &str, actual: &nimbus::scene::VolumeEmission, expected: &Value) {
    let tol = f32_tol();
    for (attr, field, e) in [
        (
            "temperatureField",
            &actual.temperature,
            &expected["temperature"],
        ),
        ("emissionField", &actual.emission, &expected["emission"]),
    ] {
        match (field, e.as_array()) {
            (None, None) => {}
            (Some((name, f)), Some(pair)) => {
                assert_eq!(name, pair[0].as_str().unwrap(), "{what} {attr}");
                assert_field(&format!("{what} {attr}"), f, &pair[1]);
            }
            (a, _) => panic!("{what} {attr}: got {a:?}, pxr says {e}"),
        }
    }
    assert_num(
        "temperatureScale",
        actual.temperature_scale,
        &expected["temperature_scale"],
        tol,
    );
    assert_num(
        "blackbodyIntensity",
        actual.blackbody_intensity,
        &expected["blackbody_intensity"],
        tol,
    );
    assert_vec(
        "emissionColor",
        &actual.emission_color,
        &expected["emission_color"],
        tol,
    );
    assert_num(
        "emissionScale",
        actual.emission_scale,
        &expected["emission_scale"],
        tol,
    );
}

/// The blackbody emission model against pxr: intensity · (T/1000 K)⁴ ·
/// `UsdLux.BlackbodyTemperatureAsRgb(T)` (pxr evaluates the colour in float: relative
/// tolerance 1e-5 of the largest channel).
#[test]
fn blackbody_emission_matches_pxr() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    for case in expected["blackbody_emission"].as_array().unwrap() {
        let (t, i) = (num(&case[0]), num(&case[1]));
        let e: Vec<f64> = case[2].as_array().unwrap().iter().map(num).collect();
        let got = nimbus::volume::emission::blackbody_radiance(t, i);
        let scale = e.iter().cloned().fold(0.0, f64::max);
        for c in 0..3 {
            assert!(
                (got[c] - e[c]).abs() <= 1e-5 * scale,
                "{t} K × {i}: got {got:?}, pxr says {e:?}"
            );
        }
    }
}

fn assert_scene(scene: &Scene, expected: &Value) {
    let tol = f32_tol();
    // Camera (chosen through the render settings' camera relationship).
    let cam = &expected["camera"];
    assert_eq!(scene.camera.prim_path, cam["prim_path"].as_str().unwrap());
    assert_transform(
        "camera",
        &scene.camera.camera_to_world,
        &cam["world"],
        &cam["probe"],
    );
    assert_num(
        "focal",
        scene.camera.focal_length,
        &cam["focal_length"],
        tol,
    );
    assert_num(
        "hap",
        scene.camera.horizontal_aperture,
        &cam["horizontal_aperture"],
        tol,
    );
    assert_num(
        "vap",
        scene.camera.vertical_aperture,
        &cam["vertical_aperture"],
        tol,
    );
    assert_num(
        "hoff",
        scene.camera.horizontal_aperture_offset,
        &cam["horizontal_aperture_offset"],
        tol,
    );
    assert_num(
        "voff",
        scene.camera.vertical_aperture_offset,
        &cam["vertical_aperture_offset"],
        tol,
    );
    let clip = [scene.camera.clipping_range.0, scene.camera.clipping_range.1];
    assert_vec("clipping", &clip, &cam["clipping_range"], tol);

    assert_volumes(scene, expected);

    // Lights.
    let distant = expected["distant_lights"].as_array().unwrap();
    assert_eq!(scene.distant_lights.len(), distant.len(), "distant lights");
    for (l, e) in scene.distant_lights.iter().zip(distant) {
        assert_eq!(l.prim_path, e["prim_path"].as_str().unwrap());
        assert_vec("direction", &l.direction, &e["direction"], REL_TOL);
        assert_num("intensity", l.intensity, &e["intensity"], tol);
        assert_num("exposure", l.exposure, &e["exposure"], tol);
        assert_vec("color", &l.color, &e["color"], tol);
        assert_num("angle", l.angle_degrees, &e["angle_degrees"], tol);
    }
    let dome = expected["dome_lights"].as_array().unwrap();
    assert_eq!(scene.dome_lights.len(), dome.len(), "dome lights");
    for (l, e) in scene.dome_lights.iter().zip(dome) {
        assert_eq!(l.prim_path, e["prim_path"].as_str().unwrap());
        assert_num("dome intensity", l.intensity, &e["intensity"], tol);
        assert_num("dome exposure", l.exposure, &e["exposure"], tol);
        assert_vec("dome color", &l.color, &e["color"], tol);
        assert_eq!(
            l.texture_file.as_deref(),
            e["texture_file"].as_str(),
            "dome texture"
        );
    }

    // Render settings.
    let s = &expected["settings"];
    assert_eq!(scene.settings.prim_path.as_deref(), s["prim_path"].as_str());
    let res = s["resolution"].as_array().unwrap();
    assert_eq!(
        scene.settings.resolution,
        (
            res[0].as_u64().unwrap() as u32,
            res[1].as_u64().unwrap() as u32
        )
    );
    assert_eq!(
        scene.settings.samples as u64,
        s["samples"].as_u64().unwrap(),
        "samples"
    );
    assert_eq!(
        scene.settings.max_depth as u64,
        s["max_depth"].as_u64().unwrap(),
        "maxDepth"
    );
    assert_eq!(scene.settings.seed, s["seed"].as_u64().unwrap(), "seed");
    assert_products(&scene.settings.products, &s["products"]);
}

// ----- pxr comparison tests -------------------------------------------------------------------

#[test]
fn stages_match_pxr() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    let cases = expected["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 6, "usda/usdc/usdz x default/frame 5");
    for case in cases {
        let stage = PathBuf::from(case["stage"].as_str().unwrap());
        let frame = case["frame"].as_f64();
        let opts = LoadOptions {
            frame,
            camera: None,
        };
        let scene = load_stage(&stage, &opts)
            .unwrap_or_else(|e| panic!("{} @ {frame:?}: {e}", stage.display()));
        eprintln!("checking {} @ {frame:?}", stage.display());
        assert_scene(&scene, case);
        match frame {
            Some(f) => assert_eq!(scene.time, f),
            None => assert!(scene.time.is_nan(), "default time is reported as NaN"),
        }
    }
}

/// A VDB frame sequence (time samples on `filePath`, no default value) with an
/// animated transform and densityScale, as .usda and packaged as .usdz: before,
/// between, on and after the samples, the file (held), transform and scale
/// (interpolated) match pxr.
#[test]
fn time_sampled_file_paths_match_pxr() {
    let Some((dir, expected)) = generate_fixtures() else {
        return;
    };
    let cases = expected["sequence_cases"].as_array().unwrap();
    assert_eq!(cases.len(), 12, "usda/usdz x 6 times");
    for case in cases {
        let stage = PathBuf::from(case["stage"].as_str().unwrap());
        let frame = case["frame"].as_f64();
        let opts = LoadOptions {
            frame,
            camera: None,
        };
        let scene = load_stage(&stage, &opts)
            .unwrap_or_else(|e| panic!("{} @ {frame:?}: {e}", stage.display()));
        eprintln!("checking {} @ {frame:?}", stage.display());
        assert_volumes(&scene, case);
    }
    // At the default time a samples-only filePath has no value in USD: the error says
    // why and what to do.
    let e = load_stage(&dir.path().join("sequence.usda"), &LoadOptions::default())
        .expect_err("no default filePath")
        .to_string();
    assert!(
        e.contains("/Fire/density") && e.contains("only time samples") && e.contains("--frame"),
        "{e}"
    );
}

/// Two RenderProducts sharing a RenderVar, vars out of namespace order: the products,
/// their names and their ordered vars match pxr.
#[test]
fn render_products_match_pxr() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    let case = &expected["products_case"];
    let stage = PathBuf::from(case["stage"].as_str().unwrap());
    let scene = load_stage(&stage, &LoadOptions::default()).expect("products.usda loads");
    assert_eq!(scene.settings.products.len(), 2);
    assert_products(&scene.settings.products, &case["settings"]["products"]);
}

/// Volumes shaded by bound materials and no Nimbus schema (RenderMan PxrVolume bound
/// directly and through an ancestor, a MaterialX volume → anisotropic_vdf network with
/// an interface-driven input) read the parameters the README's mapping gives for what
/// pxr resolves; NimbusVolumeAPI wins over a bound material.
#[test]
fn volume_materials_match_pxr() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    let case = &expected["shading_case"];
    let stage = PathBuf::from(case["stage"].as_str().unwrap());
    let scene = load_stage(&stage, &LoadOptions::default()).expect("shading.usda loads");
    assert_volumes(&scene, case);
    for (v, e) in scene
        .volumes
        .iter()
        .zip(case["volumes"].as_array().unwrap())
    {
        assert_eq!(
            v.material_shader.as_deref(),
            e["material_shader"].as_str(),
            "{} shader",
            v.prim_path
        );
    }
    assert_eq!(
        scene
            .volumes
            .iter()
            .filter(|v| v.material_shader.is_some())
            .count(),
        3
    );
}

/// A material whose volume input is driven by another shader, or whose volume shader
/// Nimbus does not read, is an error naming the shader and the input.
#[test]
fn unreadable_volume_materials() {
    let dir = tempfile::tempdir().unwrap();
    // Never opened: loading a stage only resolves the path.
    write(dir.path(), "x.vdb", "placeholder");
    let stage = |name: &str, shader: &str| {
        write(
            dir.path(),
            name,
            &format!(
                r#"#usda 1.0
{CAMERA}
def Volume "Vol" (prepend apiSchemas = ["MaterialBindingAPI"])
{{
    rel field:density = </Vol/density>
    rel material:binding = </Mat>
    def OpenVDBAsset "density" {{ asset filePath = @./x.vdb@ }}
}}
def Material "Mat"
{{
    token outputs:ri:volume.connect = </Mat/Shader.outputs:bxdf_out>
    def Shader "Shader"
    {{
        {shader}
    }}
    def Shader "Noise"
    {{
        uniform token info:id = "PxrWorley"
        color3f outputs:resultRGB
    }}
}}
"#
            ),
        )
    };
    let e = load_err(&stage(
        "driven.usda",
        r#"uniform token info:id = "PxrVolume"
        color3f inputs:diffuseColor.connect = </Mat/Noise.outputs:resultRGB>"#,
    ))
    .to_string();
    assert!(
        e.contains("/Mat/Shader") && e.contains("inputs:diffuseColor") && e.contains("constant"),
        "{e}"
    );
    let e = load_err(&stage(
        "unknown.usda",
        r#"uniform token info:id = "arnold:standard_volume""#,
    ))
    .to_string();
    assert!(
        e.contains("arnold:standard_volume") && e.contains("NimbusVolumeAPI"),
        "{e}"
    );
}

#[test]
fn camera_override() {
    let Some((dir, expected)) = generate_fixtures() else {
        return;
    };
    let stage = dir.path().join("scene.usda");
    let opts = LoadOptions {
        frame: None,
        camera: Some("/Cam2".into()),
    };
    let scene = load_stage(&stage, &opts).expect("load with camera override");
    let cam = &expected["cases"][0]["cam2"];
    assert_eq!(scene.camera.prim_path, "/Cam2");
    assert_transform(
        "cam2",
        &scene.camera.camera_to_world,
        &cam["world"],
        &cam["probe"],
    );
    // All UsdGeom fallbacks.
    assert_num(
        "focal",
        scene.camera.focal_length,
        &cam["focal_length"],
        1e-6,
    );
    assert_num(
        "hap",
        scene.camera.horizontal_aperture,
        &cam["horizontal_aperture"],
        1e-6,
    );
    assert_num(
        "vap",
        scene.camera.vertical_aperture,
        &cam["vertical_aperture"],
        1e-6,
    );
    let clip = [scene.camera.clipping_range.0, scene.camera.clipping_range.1];
    assert_vec("clipping", &clip, &cam["clipping_range"], 1e-6);

    // Not a camera: a clear error naming the prim.
    let opts = LoadOptions {
        frame: None,
        camera: Some("/World/Clouds".into()),
    };
    let err = load_stage(&stage, &opts).expect_err("an Xform is not a camera");
    assert!(err.to_string().contains("/World/Clouds"), "{err}");
    let opts = LoadOptions {
        frame: None,
        camera: Some("/Nope".into()),
    };
    let err = load_stage(&stage, &opts).expect_err("missing camera prim");
    assert!(err.to_string().contains("/Nope"), "{err}");
}

#[test]
fn pxr_and_openusd_agree_on_schema_fallbacks() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    let registry = nimbus::scene::schema::registry().expect("registry");
    for (api, props) in expected["schema"].as_object().unwrap() {
        let def = registry
            .api_prim_definition(&openusd::tf::Token::from(api.as_str()))
            .unwrap_or_else(|| panic!("openusd does not know {api}"));
        for (name, e) in props.as_object().unwrap() {
            let value = def
                .attribute_fallback(&openusd::tf::Token::from(name.as_str()))
                .unwrap_or_else(|| panic!("{api}.{name}: no fallback in openusd"));
            let actual = fallback_json(&value);
            assert_eq!(actual, *e, "{api}.{name}");
        }
    }
}

fn fallback_json(value: &openusd::sdf::Value) -> Value {
    use openusd::sdf::Value as V;
    match value {
        V::Float(f) => serde_json::json!(f64::from(*f)),
        V::Int(i) => serde_json::json!(i),
        V::Bool(b) => serde_json::json!(b),
        V::Token(t) => serde_json::json!(t.as_str()),
        V::Vec3f(v) => serde_json::json!([f64::from(v.x), f64::from(v.y), f64::from(v.z)]),
        other => panic!("unexpected fallback type {other:?}"),
    }
}

// ----- bad input (no pxr needed) -----------------------------------------------------------

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write fixture");
    path
}

const CAMERA: &str = "def Camera \"Cam\" {}\n";

fn load_err(path: &Path) -> SceneError {
    match load_stage(path, &LoadOptions::default()) {
        Ok(scene) => panic!("{} loaded: {scene:?}", path.display()),
        Err(e) => {
            // Shown with --nocapture, to eyeball that messages are readable.
            eprintln!("{}: {e}", path.display());
            e
        }
    }
}

#[test]
fn missing_stage_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nope.usda");
    let err = load_err(&path);
    assert!(err.to_string().contains("nope.usda"), "{err}");
}

#[test]
fn malformed_usda() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "broken.usda",
        "#usda 1.0\ndef Xform \"A\" {\n  float x = \n",
    );
    let err = load_err(&path);
    assert!(err.to_string().contains("broken.usda"), "{err}");
}

#[test]
fn malformed_usda_mid_file() {
    let dir = tempfile::tempdir().unwrap();
    let text = "#usda 1.0\ndef Xform \"A\" {\n    float x = 1\n    }}} garbage (\n}\ndef Camera \"C\" {}\n";
    let path = write(dir.path(), "garbage.usda", text);
    let err = load_err(&path);
    assert!(err.to_string().contains("garbage.usda"), "{err}");
}

#[test]
fn not_usd_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "junk.usdc", "this is not a crate file");
    let err = load_err(&path);
    assert!(err.to_string().contains("junk.usdc"), "{err}");
}

#[test]
fn volume_without_fields() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("#usda 1.0\n{CAMERA}def Volume \"Empty\" {{}}\n");
    let path = write(dir.path(), "nofields.usda", &text);
    let err = load_err(&path);
    assert!(
        matches!(&err, SceneError::Prim { prim, .. } if prim == "/Empty"),
        "{err}"
    );
}

#[test]
fn field_targets_missing_prim() {
    let dir = tempfile::tempdir().unwrap();
    let text =
        format!("#usda 1.0\n{CAMERA}def Volume \"V\" {{\n    rel field:density = </V/ghost>\n}}\n");
    let path = write(dir.path(), "ghost.usda", &text);
    let err = load_err(&path);
    let msg = err.to_string();
    assert!(msg.contains("/V") && msg.contains("/V/ghost"), "{msg}");
}

#[test]
fn density_field_not_openvdb() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!(
        "#usda 1.0\n{CAMERA}def Volume \"V\" {{\n    rel field:density = </V/f3d>\n    def Field3DAsset \"f3d\" {{}}\n}}\n"
    );
    let path = write(dir.path(), "f3d.usda", &text);
    let msg = load_err(&path).to_string();
    assert!(msg.contains("/V") && msg.contains("OpenVDBAsset"), "{msg}");
}

#[test]
fn named_density_field_missing() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.vdb"), b"x").unwrap();
    let text = format!(
        "#usda 1.0\n{CAMERA}def Volume \"V\" (apiSchemas = [\"NimbusVolumeAPI\"]) {{\n    token nimbus:densityField = \"smoke\"\n    rel field:density = </V/d>\n    def OpenVDBAsset \"d\" {{ asset filePath = @./a.vdb@ }}\n}}\n"
    );
    let path = write(dir.path(), "named.usda", &text);
    let msg = load_err(&path).to_string();
    assert!(msg.contains("/V") && msg.contains("field:smoke"), "{msg}");
}

#[test]
fn missing_reference() {
    let dir = tempfile::tempdir().unwrap();
    let text =
        format!("#usda 1.0\n{CAMERA}def Xform \"A\" (references = @./does_not_exist.usda@) {{}}\n");
    let path = write(dir.path(), "badref.usda", &text);
    let msg = load_err(&path).to_string();
    assert!(
        msg.contains("badref.usda") && msg.contains("does_not_exist.usda"),
        "{msg}"
    );
}

#[test]
fn missing_sublayer() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("#usda 1.0\n(\n    subLayers = [@./gone.usda@]\n)\n{CAMERA}");
    let path = write(dir.path(), "badsub.usda", &text);
    let msg = load_err(&path).to_string();
    assert!(
        msg.contains("badsub.usda") && msg.contains("gone.usda"),
        "{msg}"
    );
}

/// A stage without a camera loads with the placeholder the session replaces by a
/// default camera framing the volumes (usdrecord's convention); one that names a camera
/// that is not there is still an error naming it.
#[test]
fn no_camera() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "nocam.usda", "#usda 1.0\ndef Xform \"A\" {}\n");
    let scene = load_stage(&path, &LoadOptions::default()).unwrap();
    assert_eq!(
        scene.camera.prim_path,
        nimbus::scene::defaults::DEFAULT_CAMERA
    );
    let opts = LoadOptions {
        camera: Some("/Missing".into()),
        ..LoadOptions::default()
    };
    let msg = load_stage(&path, &opts).unwrap_err().to_string();
    assert!(msg.contains("/Missing"), "{msg}");
}

#[test]
fn minimal_stage_uses_schema_fallbacks() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("vdb")).unwrap();
    std::fs::write(dir.path().join("vdb/a.vdb"), b"x").unwrap();
    let text = format!(
        "#usda 1.0\n{CAMERA}def Volume \"V\" (apiSchemas = [\"NimbusVolumeAPI\"]) {{\n    rel field:density = </V/d>\n    def OpenVDBAsset \"d\" {{ asset filePath = @./vdb/a.vdb@ }}\n}}\ndef DistantLight \"Sun\" {{}}\ndef RenderSettings \"RS\" (apiSchemas = [\"NimbusRenderSettingsAPI\"]) {{}}\n"
    );
    let path = write(dir.path(), "min.usda", &text);
    let scene = load_stage(&path, &LoadOptions::default()).expect("loads");
    let v = &scene.volumes[0];
    assert_eq!(v.density_scale, 1.0);
    assert_eq!(v.absorption, [f64::from(0.1f32); 3]);
    assert_eq!(v.scattering, [f64::from(0.9f32); 3]);
    assert_eq!(v.anisotropy, 0.0);
    assert_eq!(v.shape.field().unwrap().field_index, None);
    assert_eq!(v.shape.field().unwrap().field_name, "");
    assert_eq!(v.volume_to_world, DMat4::IDENTITY);
    let sun = &scene.distant_lights[0];
    // UsdLux overrides the LightAPI intensity fallback (1) with 50000 for a
    // DistantLight; pxr reports the same.
    assert_eq!(
        (sun.intensity, sun.exposure, sun.color),
        (50000.0, 0.0, [1.0; 3])
    );
    assert!((sun.angle_degrees - 0.53).abs() < 1e-6);
    assert_eq!(sun.direction, [0.0, 0.0, 1.0]);
    assert_eq!(
        (
            scene.settings.samples,
            scene.settings.max_depth,
            scene.settings.seed
        ),
        (16, 64, 0)
    );
    assert_eq!(scene.settings.prim_path.as_deref(), Some("/RS"));
}
