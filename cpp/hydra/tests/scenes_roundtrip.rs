//! The Rust half of hdNimbus against the USD reader on the example stages
//! (`scenes/*`): each stage's `Scene`, handed over in the plain structs the C++ half
//! fills from Hydra (camera lengths in scene units, light and volume parameters by
//! their Hydra names, NimbusVolumeAPI's attributes as `nimbus:*` primvars, holdouts as
//! meshes), comes back from `scene_of` as the same scene — everything but what Hydra
//! does not carry (the stage path and time, render products, a holdout's polygon
//! count) — and renders bit for bit the same image through `Session::from_scene`.
//!
//! This checks the conversion the delegate adds; what Hydra hosts hand over is checked
//! in Blender (`tests/hydra_blender.rs` at the root).

use glam::{DMat4, DVec3};
use hd_nimbus::ffi::bridge::{
    CameraDesc, FieldDesc, LightDesc, MeshDesc, ParamDesc, SceneDesc, SettingDesc, VolumeDesc,
};
use hd_nimbus::scene::scene_of;
use nimbus::render::film::Aov;
use nimbus::render::session::{Overrides, Session};
use nimbus::scene::{load_stage, Field, LightControls, LoadOptions, Scene, VolumeShape};
use nimbus::volume::asset::AssetLocation;
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn field(name: &str, f: &Field) -> FieldDesc {
    let AssetLocation::File(file) = &f.file else {
        panic!("{}: a packaged field", f.prim_path)
    };
    FieldDesc {
        name: name.into(),
        path: f.prim_path.clone(),
        prim_type: "openvdbAsset".into(),
        file: file.display().to_string(),
        grid: f.field_name.clone(),
        index: f.field_index.unwrap_or(-1),
    }
}

fn number(name: &str, v: f64) -> ParamDesc {
    ParamDesc {
        name: format!("primvars:{name}"),
        numbers: vec![v],
        text: String::new(),
    }
}

fn color(name: &str, v: [f64; 3]) -> ParamDesc {
    ParamDesc {
        name: format!("primvars:{name}"),
        numbers: v.to_vec(),
        text: String::new(),
    }
}

fn token(name: &str, v: &str) -> ParamDesc {
    ParamDesc {
        name: format!("primvars:{name}"),
        numbers: Vec::new(),
        text: v.into(),
    }
}

fn light(kind: &str, path: &str, to_world: DMat4, c: &LightControls) -> LightDesc {
    let s = c.shaping.clone().unwrap_or_default();
    LightDesc {
        kind: kind.into(),
        path: path.into(),
        xform: to_world.to_cols_array(),
        diffuse: c.diffuse,
        shadow_enable: !c.unshadowed,
        has_shaping: c.shaping.is_some(),
        shaping_focus: s.focus,
        shaping_focus_tint: s.focus_tint,
        shaping_cone_angle: s.cone_angle,
        shaping_cone_softness: s.cone_softness,
        shaping_ies_file: s.ies_file.unwrap_or_default(),
        shaping_ies_angle_scale: s.ies_angle_scale,
        shaping_ies_normalize: s.ies_normalize,
        ..LightDesc::default()
    }
}

/// `scene` as the C++ half would hand it over from Hydra.
fn desc_of(scene: &Scene) -> SceneDesc {
    let c = &scene.camera;
    let mut d = SceneDesc {
        has_camera: true,
        camera: CameraDesc {
            path: c.prim_path.clone(),
            xform: c.camera_to_world.to_cols_array(),
            orthographic: c.projection == nimbus::scene::Projection::Orthographic,
            focal_length: c.focal_length / 10.0,
            horizontal_aperture: c.horizontal_aperture / 10.0,
            vertical_aperture: c.vertical_aperture / 10.0,
            horizontal_aperture_offset: c.horizontal_aperture_offset / 10.0,
            vertical_aperture_offset: c.vertical_aperture_offset / 10.0,
            near: c.clipping_range.0,
            far: c.clipping_range.1,
            f_stop: c.f_stop,
            focus_distance: c.focus_distance,
            shutter_open: c.shutter.map_or(0.0, |s| s.0),
            shutter_close: c.shutter.map_or(0.0, |s| s.1),
            // The example stages do not move (a moving camera's samples: the unit
            // test of `scene`, tests/hydra_host.rs).
            xform_samples: Vec::new(),
        },
        width: scene.settings.resolution.0,
        height: scene.settings.resolution.1,
        ..SceneDesc::default()
    };
    macro_rules! common {
        ($l:expr, $d:expr) => {{
            $d.intensity = $l.intensity;
            $d.exposure = $l.exposure;
            $d.color = $l.color;
            $d.enable_color_temperature = $l.color_temperature.is_some();
            $d.color_temperature = $l.color_temperature.unwrap_or(6500.0);
            $d.light_group = $l.light_group.clone().unwrap_or_default();
        }};
    }
    for l in &scene.distant_lights {
        // A light → world matrix whose +Z is the direction towards the light.
        let z = DVec3::from_array(l.direction);
        let x = z.any_orthonormal_vector();
        let m = DMat4::from_cols(
            x.extend(0.0),
            z.cross(x).extend(0.0),
            z.extend(0.0),
            glam::DVec4::W,
        );
        let mut ld = light("distantLight", &l.prim_path, m, &l.controls);
        common!(l, ld);
        ld.normalize = l.normalize;
        ld.angle = l.angle_degrees;
        d.lights.push(ld);
    }
    for l in &scene.dome_lights {
        let mut ld = light("domeLight", &l.prim_path, l.light_to_world, &l.controls);
        common!(l, ld);
        ld.texture_file = l.texture_file.clone().unwrap_or_default();
        ld.texture_format = l.texture_format.clone();
        d.lights.push(ld);
    }
    for l in &scene.sphere_lights {
        let mut ld = light("sphereLight", &l.prim_path, l.light_to_world, &l.controls);
        common!(l, ld);
        ld.normalize = l.normalize;
        ld.radius = l.radius;
        ld.treat_as_point = l.treat_as_point;
        ld.lights_interior = l.lights_interior;
        d.lights.push(ld);
    }
    for l in &scene.rect_lights {
        let mut ld = light("rectLight", &l.prim_path, l.light_to_world, &l.controls);
        common!(l, ld);
        ld.normalize = l.normalize;
        ld.width = l.width;
        ld.height = l.height;
        d.lights.push(ld);
    }
    for l in &scene.disk_lights {
        let mut ld = light("diskLight", &l.prim_path, l.light_to_world, &l.controls);
        common!(l, ld);
        ld.normalize = l.normalize;
        ld.radius = l.radius;
        d.lights.push(ld);
    }
    for l in &scene.cylinder_lights {
        let mut ld = light("cylinderLight", &l.prim_path, l.light_to_world, &l.controls);
        common!(l, ld);
        ld.normalize = l.normalize;
        ld.length = l.length;
        ld.radius = l.radius;
        ld.treat_as_line = l.treat_as_line;
        d.lights.push(ld);
    }
    for v in &scene.volumes {
        let e = &v.emission;
        let mut primvars = vec![
            number("nimbus:densityScale", v.density_scale),
            color("nimbus:absorption", v.absorption),
            color("nimbus:scattering", v.scattering),
            number("nimbus:anisotropy", v.anisotropy),
            number("nimbus:temperatureScale", e.temperature_scale),
            number("nimbus:blackbodyIntensity", e.blackbody_intensity),
            color("nimbus:emissionColor", e.emission_color),
            number("nimbus:emissionScale", e.emission_scale),
            token("nimbus:emissionKind", e.kind.token()),
        ];
        // A medium from a material: the material's shader and its parameters instead
        // (ND_anisotropic_vdf's are the coefficients themselves).
        let mut material = (String::new(), String::new(), String::new(), Vec::new());
        if let Some(shader) = &v.material_shader {
            let (path, id) = shader
                .strip_suffix(')')
                .and_then(|s| s.split_once(" ("))
                .expect("\"shader (id)\"");
            assert_eq!(id, "ND_anisotropic_vdf", "{}", v.prim_path);
            let plain = |p: ParamDesc| ParamDesc {
                name: p.name.trim_start_matches("primvars:nimbus:").into(),
                ..p
            };
            primvars.clear();
            material = (
                path.rsplit_once('/').map_or("", |(m, _)| m).to_string(),
                path.to_string(),
                id.to_string(),
                vec![
                    plain(color("nimbus:absorption", v.absorption)),
                    plain(color("nimbus:scattering", v.scattering)),
                    plain(number("nimbus:anisotropy", v.anisotropy)),
                ],
            );
        }
        if let Some(g) = &v.light_group {
            primvars.push(token("nimbus:lightGroup", g));
        }
        let (material_path, shader_path, shader_id, shader_params) = material;
        match &v.shape {
            VolumeShape::Mesh(fog) => {
                d.meshes.push(MeshDesc {
                    path: v.prim_path.clone(),
                    xform: v.volume_to_world.to_cols_array(),
                    points: fog.mesh.points.iter().flatten().copied().collect(),
                    face_counts: vec![3; fog.mesh.triangles.len()],
                    face_indices: fog
                        .mesh
                        .triangles
                        .iter()
                        .flatten()
                        .map(|&i| i as i32)
                        .collect(),
                    double_sided: fog.mesh.double_sided,
                    primvars,
                    material_path,
                    shader_path,
                    shader_id,
                    shader_params,
                    ..MeshDesc::default()
                });
                continue;
            }
            VolumeShape::World => primvars.push(token("nimbus:fill", "world")),
            VolumeShape::Field(density) => {
                let density = v
                    .fields
                    .iter()
                    .find(|(_, f)| f == density)
                    .map(|(n, _)| n.clone())
                    .expect("the density among the fields");
                primvars.push(token("nimbus:densityField", &density));
            }
        }
        for (attr, f) in [
            ("nimbus:temperatureField", &e.temperature),
            ("nimbus:emissionField", &e.emission),
            ("nimbus:albedoField", &v.albedo),
        ] {
            if let Some((name, _)) = f {
                primvars.push(token(attr, name));
            }
        }
        d.volumes.push(VolumeDesc {
            path: v.prim_path.clone(),
            xform: v.volume_to_world.to_cols_array(),
            fields: v.fields.iter().map(|(n, f)| field(n, f)).collect(),
            primvars,
            material_path,
            shader_path,
            shader_id,
            shader_params,
            ..VolumeDesc::default()
        });
    }
    for h in &scene.holdouts {
        d.meshes.push(MeshDesc {
            path: h.prim_path.clone(),
            xform: DMat4::IDENTITY.to_cols_array(),
            points: h.points.iter().flatten().copied().collect(),
            face_counts: vec![3; h.triangles.len()],
            face_indices: h.triangles.iter().flatten().map(|&i| i as i32).collect(),
            hole_indices: Vec::new(),
            double_sided: h.double_sided,
            ..MeshDesc::default()
        });
    }
    let s = &scene.settings;
    let num = |key: &str, v: f64| SettingDesc {
        key: key.into(),
        is_text: false,
        number: v,
        text: String::new(),
    };
    let tok = |key: &str, v: &str| SettingDesc {
        key: key.into(),
        is_text: true,
        number: 0.0,
        text: v.into(),
    };
    d.settings.push(num("nimbus:samples", s.samples as f64));
    d.settings.push(num("nimbus:maxDepth", s.max_depth as f64));
    d.settings.push(num("nimbus:seed", s.seed as f64));
    d.settings.push(num("nimbus:strict", s.strict as u8 as f64));
    for (key, v) in [
        ("nimbus:tracker", &s.tracker),
        ("nimbus:scheme", &s.scheme),
        ("nimbus:transmittance", &s.transmittance),
    ] {
        if let Some(v) = v {
            d.settings.push(tok(key, v));
        }
    }
    if let Some(c) = s.control {
        d.settings.push(num("nimbus:control", c));
    }
    if let Some(o) = s.octree_depth {
        d.settings.push(num("nimbus:octreeDepth", o as f64));
    }
    d
}

/// What Hydra does not carry, set alike in both scenes.
fn comparable(mut s: Scene) -> Scene {
    s.stage_path = PathBuf::from("-");
    s.time = 0.0;
    s.settings.prim_path = None;
    s.settings.products.clear();
    s.warnings = Default::default();
    let fog_surfaces = s.volumes.iter_mut().filter_map(|v| match &mut v.shape {
        VolumeShape::Mesh(fog) => Some(&mut fog.mesh),
        _ => None,
    });
    for h in s.holdouts.iter_mut().chain(fog_surfaces) {
        h.faces = 0;
        h.degenerate_triangles = 0;
        h.prim_type = "Mesh".into();
    }
    s
}

fn stages() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("scenes"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| {
            std::fs::read_dir(e.path())
                .ok()?
                .filter_map(|f| f.ok())
                .map(|f| f.path())
                .find(|p| p.extension().is_some_and(|x| x == "usda"))
        })
        .collect();
    v.sort();
    v
}

#[test]
fn example_stages_convert_back_and_render_bit_identically() {
    let stages = stages();
    assert!(stages.len() >= 4, "scenes/*: {stages:?}");
    for stage in stages {
        let read = load_stage(&stage, &LoadOptions::default())
            .unwrap_or_else(|e| panic!("{}: {e:#}", stage.display()));
        round_trip(&stage, read);
    }
}

/// The cloud example with fog (`tests/fog.rs`, docs/usd.md): world fog in its own
/// light group, a fog Cube (NimbusVolumeAPI, emitting as a source) rotated and scaled,
/// and a prism Mesh bound to an `ND_anisotropic_vdf` material, handed over as hdNimbus
/// receives them (the gprims as meshes with their `nimbus:*` primvars or their
/// material's volume shader, world fog as a Volume with the `nimbus:fill` primvar).
#[test]
fn fog_stage_converts_back_and_renders_bit_identically() {
    let dir = std::env::temp_dir().join(format!("hdnimbus-fog-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(repo().join("scenes/cloud/cloud.usda")).unwrap();
    let fog = r#"
    def Volume "Haze" (
        prepend apiSchemas = ["NimbusVolumeAPI"]
    )
    {
        uniform token nimbus:fill = "world"
        float nimbus:densityScale = 0.03
        token nimbus:lightGroup = "air"
    }

    def Cube "Box" (
        prepend apiSchemas = ["NimbusVolumeAPI"]
    )
    {
        double size = 0.8
        float nimbus:densityScale = 3
        color3f nimbus:absorption = (0.5, 0.3, 0.2)
        color3f nimbus:scattering = (0.2, 0.4, 0.6)
        uniform token nimbus:emissionKind = "source"
        color3f nimbus:emissionColor = (1, 0.4, 0.1)
        float nimbus:emissionScale = 2
        double3 xformOp:translate = (-1.1, -0.6, 0.5)
        float3 xformOp:rotateXYZ = (20, 35, 50)
        float3 xformOp:scale = (1.5, 0.8, 1.1)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ", "xformOp:scale"]
    }

    def Mesh "Prism" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {
        rel material:binding = </World/Mist>
        point3f[] points = [(0, 0, 0), (0.8, 0, 0), (0.4, 0.7, 0), (0, 0, 0.6), (0.8, 0, 0.6), (0.4, 0.7, 0.6)]
        int[] faceVertexCounts = [3, 3, 4, 4, 4]
        int[] faceVertexIndices = [0, 2, 1, 3, 4, 5, 0, 1, 4, 3, 1, 2, 5, 4, 2, 0, 3, 5]
        double3 xformOp:translate = (0.6, -0.9, 0.4)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }

    def Material "Mist"
    {
        token outputs:mtlx:volume.connect = </World/Mist/vdf.outputs:out>
        def Shader "vdf"
        {
            uniform token info:id = "ND_anisotropic_vdf"
            color3f inputs:absorption = (0.1, 0.2, 0.3)
            color3f inputs:scattering = (1.5, 1.2, 0.9)
            float inputs:anisotropy = 0.3
            token outputs:out
        }
    }
"#;
    let at = text.find("    def Camera \"Camera\"").unwrap();
    let text = format!("{}{fog}\n{}", &text[..at], &text[at..]).replace(
        "@./cloud.vdb@",
        &format!("@{}@", repo().join("scenes/cloud/cloud.vdb").display()),
    );
    let stage = dir.join("fog.usda");
    std::fs::write(&stage, text).unwrap();
    let read = load_stage(&stage, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e:#}"));
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(read.warnings.is_empty(), "{:?}", read.warnings.lines());
    let shapes: Vec<(&str, &str)> = read
        .volumes
        .iter()
        .map(|v| {
            let shape = match &v.shape {
                VolumeShape::Field(_) => "field",
                VolumeShape::Mesh(m) if m.closed => "closed fog box",
                VolumeShape::Mesh(_) => "open fog box",
                VolumeShape::World => "world fog",
            };
            (v.prim_path.as_str(), shape)
        })
        .collect();
    assert_eq!(
        shapes,
        [
            ("/World/Cloud", "field"),
            ("/World/Haze", "world fog"),
            ("/World/Box", "closed fog box"),
            ("/World/Prism", "closed fog box"),
        ]
    );
    assert!(read.holdouts.is_empty());
    round_trip(&stage, read);
}

/// `read` (the USD reader's scene of `stage`) handed over as Hydra structs comes back
/// from `scene_of` as the same scene and renders the same image.
fn round_trip(stage: &Path, read: Scene) {
    {
        let (back, warnings) = scene_of(&desc_of(&read)).unwrap();
        assert!(warnings.is_empty(), "{}: {warnings:?}", stage.display());
        let (mut a, b) = (comparable(read.clone()), comparable(back.clone()));
        // Hydra's camera lengths are tenths of UsdGeomCamera's: / 10 then × 10 may
        // move the last bit.
        let (ca, cb) = (&a.camera, &b.camera);
        for (x, y) in [
            (ca.focal_length, cb.focal_length),
            (ca.horizontal_aperture, cb.horizontal_aperture),
            (ca.vertical_aperture, cb.vertical_aperture),
        ] {
            assert!(
                (x - y).abs() <= 1e-15 * x.abs(),
                "{}: camera {x} vs {y}",
                stage.display()
            );
        }
        a.camera = b.camera.clone();
        // A distant light's direction, normalised again.
        for (la, lb) in a.distant_lights.iter_mut().zip(&b.distant_lights) {
            let d = DVec3::from_array(la.direction) - DVec3::from_array(lb.direction);
            assert!(d.length() < 1e-15, "{}: direction", stage.display());
            la.direction = lb.direction;
        }
        assert_eq!(
            format!("{a:#?}"),
            format!("{b:#?}"),
            "{}: the scene through Hydra's structs differs",
            stage.display()
        );

        // The images, from the scene as read and as converted back (the camera as
        // converted: bit-identical when the / 10 × 10 round trip is exact).
        let o = Overrides {
            res: Some((48, 32)),
            spp: Some(4),
            ..Overrides::default()
        };
        let render = |scene: Scene| {
            let s = Session::from_scene(stage, scene, &o).unwrap();
            let job = s.job(false);
            let film = job.render(&|| {});
            [Aov::R, Aov::G, Aov::B, Aov::A].map(|c| film.channel(c))
        };
        let camera_exact = read.camera.focal_length == back.camera.focal_length
            && read.camera.horizontal_aperture == back.camera.horizontal_aperture
            && read.camera.vertical_aperture == back.camera.vertical_aperture;
        let (ia, ib) = (render(read), render(back));
        let same = ia
            .iter()
            .zip(&ib)
            .all(|(x, y)| x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()));
        eprintln!(
            "{}: scene equal; image bit-identical: {same} (camera lengths exact after / 10 × 10: {camera_exact})",
            stage.display()
        );
        if camera_exact {
            assert!(same, "{}: same scene, different image", stage.display());
        }
    }
}
