//! The boundary between the delegate's C++ half and its Rust half: plain structs the
//! C++ fills from what Hydra hands over (no USD types cross), and the entry points the
//! C++ calls. The entry points are thin: they convert the structs ([`crate::scene`]
//! builds the scene; [`PassState`] becomes [`bridge::PassInfo`] here) and call down
//! into [`crate::renderer`], which knows nothing of the bridge. Every entry point
//! catches panics ([`guarded`]): nothing may unwind into C++. Errors become C++
//! exceptions the C++ catches and reports through TF_RUNTIME_ERROR.
//!
//! Matrices are GfMatrix4d's 16 numbers in its memory order (row vectors, translation
//! in elements 12..15), which is column-major for column vectors: glam's
//! `DMat4::from_cols_array` reads them as they are.

// Down: the entry points convert and call these. (`scene` uses `bridge`'s structs in
// turn, the one edge back up that cxx forces: see scene.rs.)
use crate::renderer::{self, PassState};
use crate::scene::{self, scene_of, STAGE_NAME};
use anyhow::{anyhow, Result};
use bridge::{PassInfo, SceneDesc, SettingDescriptor};
use std::panic::{catch_unwind, AssertUnwindSafe};

#[cxx::bridge(namespace = "nimbus_hydra")]
pub mod bridge {
    /// One of a prim's transform samples (`HdSceneDelegate::SampleTransform`): the
    /// time, in time codes from the frame (as UsdImaging hands them), and the
    /// matrix.
    #[derive(Clone, Debug, Default)]
    struct XformSample {
        time: f64,
        xform: [f64; 16],
    }

    /// A light sprim: its Hydra type and the UsdLux parameters Hydra knows.
    #[derive(Clone, Debug, Default)]
    struct LightDesc {
        /// sphereLight, distantLight, rectLight, diskLight, cylinderLight, domeLight.
        kind: String,
        path: String,
        xform: [f64; 16],
        /// Its transform samples (a light is not blurred: moving ones warn).
        xform_samples: Vec<XformSample>,
        intensity: f64,
        exposure: f64,
        color: [f64; 3],
        normalize: bool,
        enable_color_temperature: bool,
        color_temperature: f64,
        radius: f64,
        width: f64,
        height: f64,
        length: f64,
        angle: f64,
        treat_as_point: bool,
        treat_as_line: bool,
        /// `nimbus:lightsInterior` (a sphere light's).
        lights_interior: bool,
        diffuse: f64,
        /// `texture:file` of a dome, resolved ("" when none).
        texture_file: String,
        texture_format: String,
        shadow_enable: bool,
        /// Whether any shaping parameter is present.
        has_shaping: bool,
        shaping_focus: f64,
        shaping_focus_tint: [f64; 3],
        shaping_cone_angle: f64,
        shaping_cone_softness: f64,
        shaping_ies_file: String,
        shaping_ies_angle_scale: f64,
        shaping_ies_normalize: bool,
        /// `nimbus:lightGroup`, "" when none.
        light_group: String,
        /// The `lightLink` and `shadowLink` collections by the names Hydra gives them
        /// ("" : every prim); the rprims in one list its name among their categories.
        light_link: String,
        shadow_link: String,
    }

    /// An `openvdbAsset` field bprim as a volume names it.
    #[derive(Clone, Debug, Default)]
    struct FieldDesc {
        /// The volume's name for it (`density`, `temperature`, …).
        name: String,
        /// The bprim's path and Hydra type (only `openvdbAsset` is read).
        path: String,
        prim_type: String,
        /// `filePath`, resolved; `fieldName`; `fieldIndex` (-1: not given).
        file: String,
        grid: String,
        index: i32,
    }

    /// A named parameter: numbers (a scalar or a colour) or a text.
    #[derive(Clone, Debug, Default)]
    struct ParamDesc {
        name: String,
        numbers: Vec<f64>,
        text: String,
    }

    /// A connection into a shader node's input: `input` takes the output `output` of
    /// the node at path `node` (Hydra's HdMaterialRelationship, seen downstream).
    #[derive(Clone, Debug, Default)]
    struct ConnectionDesc {
        input: String,
        node: String,
        output: String,
    }

    /// A node of a material's network: path, identifier, parameters and connected
    /// inputs.
    #[derive(Clone, Debug, Default)]
    struct ShaderNodeDesc {
        path: String,
        id: String,
        params: Vec<ParamDesc>,
        connections: Vec<ConnectionDesc>,
    }

    /// A volume rprim: its fields, its constant primvars and its material's volume
    /// shader (identifier and parameters).
    #[derive(Clone, Debug, Default)]
    struct VolumeDesc {
        path: String,
        xform: [f64; 16],
        /// Its transform samples over the shutter (the motion blur's keys).
        xform_samples: Vec<XformSample>,
        fields: Vec<FieldDesc>,
        primvars: Vec<ParamDesc>,
        material_path: String,
        shader_path: String,
        shader_id: String,
        shader_params: Vec<ParamDesc>,
        /// Every node of the material's networks (a density graph is compiled from it).
        shader_network: Vec<ShaderNodeDesc>,
        /// The light-linking collections it is in (Hydra's categories).
        categories: Vec<String>,
    }

    /// A mesh rprim: its control cage in object space, its constant primvars and its
    /// material's volume shader (a holdout, or a fog box: see `scene.rs`).
    #[derive(Clone, Debug, Default)]
    struct MeshDesc {
        path: String,
        xform: [f64; 16],
        /// Its transform samples (a mesh is not blurred: a moving one warns).
        xform_samples: Vec<XformSample>,
        points: Vec<f64>,
        face_counts: Vec<i32>,
        face_indices: Vec<i32>,
        hole_indices: Vec<i32>,
        double_sided: bool,
        /// The topology's orientation is `leftHanded` (faces wound clockwise seen
        /// from their front).
        left_handed: bool,
        /// The light-linking collections it is in (Hydra's categories).
        categories: Vec<String>,
        primvars: Vec<ParamDesc>,
        material_path: String,
        shader_path: String,
        shader_id: String,
        shader_params: Vec<ParamDesc>,
        shader_network: Vec<ShaderNodeDesc>,
    }

    /// The camera rendered through, in Hydra's units (world units, not UsdGeomCamera's
    /// tenths).
    #[derive(Clone, Debug, Default)]
    struct CameraDesc {
        path: String,
        xform: [f64; 16],
        orthographic: bool,
        focal_length: f64,
        horizontal_aperture: f64,
        vertical_aperture: f64,
        horizontal_aperture_offset: f64,
        vertical_aperture_offset: f64,
        near: f64,
        far: f64,
        f_stop: f64,
        focus_distance: f64,
        /// HdCamera's shutter (time codes from the frame; open < close: open).
        shutter_open: f64,
        shutter_close: f64,
        /// Its transform samples over the shutter (the motion blur's keys).
        xform_samples: Vec<XformSample>,
    }

    /// A render setting as the host set it: a number (ints, floats, bools) or a text.
    #[derive(Clone, Debug, Default)]
    struct SettingDesc {
        key: String,
        is_text: bool,
        number: f64,
        text: String,
    }

    /// A render setting the delegate offers the host.
    #[derive(Clone, Debug, Default)]
    struct SettingDescriptor {
        key: String,
        name: String,
        is_text: bool,
        is_int: bool,
        number: f64,
        text: String,
    }

    /// Everything one render needs.
    #[derive(Clone, Debug, Default)]
    struct SceneDesc {
        camera: CameraDesc,
        has_camera: bool,
        lights: Vec<LightDesc>,
        /// Lights of types the core lacks, as "path (type)".
        unsupported_lights: Vec<String>,
        volumes: Vec<VolumeDesc>,
        meshes: Vec<MeshDesc>,
        settings: Vec<SettingDesc>,
        width: u32,
        height: u32,
        /// How many threads the host synced prims on so far (for the statistics).
        sync_threads: u32,
        /// The AOVs the render pass is bound to (the split layers among them are
        /// gathered while rendering).
        aovs: Vec<String>,
        /// The active render settings prim's `shutterInterval` (Hydra computes it
        /// from its products' cameras), when it has one: the shutter when the camera's
        /// is closed.
        has_settings_shutter: bool,
        settings_shutter: [f64; 2],
    }

    /// Where a render stands after a pass.
    #[derive(Clone, Debug, Default)]
    struct PassInfo {
        spp: u32,
        target_spp: u32,
        converged: bool,
        /// Mean density lookups per sample so far.
        lookups_per_sample: f64,
        seconds: f64,
    }

    extern "Rust" {
        type Renderer;
        fn new_renderer() -> Box<Renderer>;
        /// Starts a new render of `scene`; returns the warnings to show.
        fn reset(self: &mut Renderer, scene: &SceneDesc) -> Result<Vec<String>>;
        /// Renders one more pass (nothing once converged).
        fn render_pass(self: &mut Renderer) -> Result<PassInfo>;
        /// Copies AOV `name` (`color`: RGBA; `depth`; Nimbus' AOVs by their channel
        /// names) into `out`, `components` floats per pixel, row 0 at the bottom as
        /// Hydra's buffers hold it. False when `name` is no AOV Nimbus has.
        fn read_aov(self: &Renderer, name: &str, components: usize, out: &mut [f32]) -> bool;
        /// One line of statistics (tracker, samples, lookups per sample, seconds).
        fn stats_line(self: &Renderer) -> String;
        /// The render settings hdNimbus reads, with their defaults.
        fn setting_descriptors() -> Vec<SettingDescriptor>;
        /// Whether `name` is an AOV hdNimbus writes.
        fn is_aov(name: &str) -> bool;
        /// Whether `name` is a split AOV (a light group, `direct`, `indirect`,
        /// `emission`, or `lpe:` and a light path expression): an RGB image.
        fn is_split_aov(name: &str) -> bool;
    }
}

/// The renderer as the C++ render pass holds it (`rust::Box<nimbus_hydra::Renderer>`):
/// [`renderer::Renderer`] behind the bridge's structs and panic guard.
pub struct Renderer {
    inner: renderer::Renderer,
}

/// The extern "Rust" entry points below are the bridge's: cxx looks them up in this
/// module (the bridge's parent), so they live here and call down.
pub fn new_renderer() -> Box<Renderer> {
    Box::new(Renderer {
        inner: renderer::Renderer::default(),
    })
}

impl Renderer {
    pub fn reset(&mut self, desc: &SceneDesc) -> Result<Vec<String>> {
        self.inner
            .clear((desc.width, desc.height), desc.sync_threads);
        guarded("reset", || {
            let (scene, warnings) = scene_of(desc)?;
            self.inner.start(scene, &desc.aovs, warnings)
        })
    }

    pub fn render_pass(&mut self) -> Result<PassInfo> {
        let result = guarded("render_pass", || Ok(pass_info(self.inner.render_pass())));
        if result.is_err() {
            self.inner.stop();
        }
        result
    }

    pub fn read_aov(&self, name: &str, components: usize, out: &mut [f32]) -> bool {
        guarded("read_aov", || {
            Ok(self.inner.read_aov(name, components, out))
        })
        .unwrap_or(false)
    }

    pub fn stats_line(&self) -> String {
        self.inner.stats_line()
    }
}

pub fn setting_descriptors() -> Vec<SettingDescriptor> {
    scene::setting_descriptors()
}

pub fn is_aov(name: &str) -> bool {
    renderer::is_aov(name)
}

pub fn is_split_aov(name: &str) -> bool {
    renderer::is_split_aov(name)
}

fn pass_info(p: PassState) -> PassInfo {
    PassInfo {
        spp: p.spp,
        target_spp: p.target_spp,
        converged: p.converged,
        lookups_per_sample: p.lookups_per_sample,
        seconds: p.seconds,
    }
}

/// Runs `f`, turning a panic into an error.
fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(anyhow!("{STAGE_NAME}: internal error in {what}: {msg}"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::bridge::{CameraDesc, LightDesc};
    use super::*;
    use crate::scene::tests::{identity, light, smoke_volume};
    use glam::DVec3;

    /// A slab of density 1 over [-1, 1]³ lit by a sun of group `key` and a sphere
    /// light of none, seen from z = 5: the bound split AOVs are filled, the groups sum
    /// to the beauty within the f32 rounding of each mean, and an AOV whose group
    /// matches nothing (or an expression Nimbus cannot split) is a warning naming it and
    /// a black buffer, not a lost render.
    #[test]
    fn split_aovs_are_filled_and_a_bad_one_is_a_warning() {
        let dir = std::env::temp_dir().join(format!("hdnimbus-aovs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let vdb = dir.join("slab.vdb");
        let vs = 2.0 / 16.0;
        let grid = nimbus::volume::procedural::grid_from_fn(
            "density",
            [16; 3],
            DVec3::splat(-1.0 + 0.5 * vs),
            vs,
            |_| 1.0,
        );
        nimbus::volume::vdb::write_float_grid(&vdb, &grid).unwrap();
        let mut volume = smoke_volume();
        volume.fields[0].file = vdb.to_str().unwrap().into();
        let sun = LightDesc {
            light_group: "key".into(),
            ..light("distantLight")
        };
        let mut bulb = light("sphereLight");
        bulb.xform[13] = 3.0;
        bulb.radius = 0.1;
        bulb.intensity = 50.0;
        let mut cam = identity();
        cam[14] = 5.0;
        let (w, h) = (8u32, 6u32);
        let desc = SceneDesc {
            camera: CameraDesc {
                path: "/cam".into(),
                xform: cam,
                focal_length: 5.0,
                horizontal_aperture: 3.6,
                vertical_aperture: 2.7,
                near: 0.1,
                far: 100.0,
                ..CameraDesc::default()
            },
            has_camera: true,
            lights: vec![sun, bulb],
            volumes: vec![volume],
            width: w,
            height: h,
            aovs: [
                "color",
                "lightgroup:key",
                "lightgroup:/sphereLight",
                "lightgroup:nothing",
                "lpe:CX",
                "lookups",
            ]
            .map(String::from)
            .to_vec(),
            ..SceneDesc::default()
        };
        let mut r = new_renderer();
        let warnings = r.reset(&desc).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        for bad in ["AOV lightgroup:nothing", "AOV lpe:CX"] {
            assert!(
                warnings.iter().any(|w| w.contains(bad)),
                "no warning naming {bad}: {warnings:?}"
            );
        }
        while !r.render_pass().unwrap().converged {}
        let n = (w * h) as usize;
        let read = |name: &str, k: usize| {
            let mut v = vec![f32::NAN; n * k];
            assert!(r.read_aov(name, k, &mut v), "{name}");
            v
        };
        let color = read("color", 4);
        let key = read("lightgroup:key", 3);
        let bulb = read("lightgroup:/sphereLight", 3);
        assert!(read("lightgroup:nothing", 3).iter().all(|&v| v == 0.0));
        let total = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>();
        assert!(total(&key) > 0.0 && total(&bulb) > 0.0);
        for p in 0..n {
            for c in 0..3 {
                let (b, s) = (
                    color[p * 4 + c] as f64,
                    key[p * 3 + c] as f64 + bulb[p * 3 + c] as f64,
                );
                let bound = (b.abs() + s.abs()) * 2f64.powi(-24) + 1e-30;
                assert!(
                    (s - b).abs() <= bound,
                    "pixel {p} channel {c}: key + bulb {s}, beauty {b}"
                );
            }
        }
    }
}
