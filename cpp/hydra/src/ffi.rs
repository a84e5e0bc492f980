//! The boundary between the delegate's C++ half and its Rust half: plain structs the
//! C++ fills from what Hydra hands over (no USD types cross), and the renderer the C++
//! drives. Every Rust function here catches panics (see `renderer`), and its errors
//! become C++ exceptions the C++ catches and reports through TF_RUNTIME_ERROR.
//!
//! Matrices are GfMatrix4d's 16 numbers in its memory order (row vectors, translation
//! in elements 12..15), which is column-major for column vectors: glam's
//! `DMat4::from_cols_array` reads them as they are.

use crate::renderer::{is_aov, is_split_aov, new_renderer, setting_descriptors, Renderer};

#[cxx::bridge(namespace = "nimbus_hydra")]
pub mod bridge {
    /// A light sprim: its Hydra type and the UsdLux parameters Hydra knows.
    #[derive(Clone, Debug, Default)]
    struct LightDesc {
        /// sphereLight, distantLight, rectLight, diskLight, cylinderLight, domeLight.
        kind: String,
        path: String,
        xform: [f64; 16],
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

    /// A volume rprim: its fields, its constant primvars and its material's volume
    /// shader (identifier and parameters).
    #[derive(Clone, Debug, Default)]
    struct VolumeDesc {
        path: String,
        xform: [f64; 16],
        fields: Vec<FieldDesc>,
        primvars: Vec<ParamDesc>,
        material_path: String,
        shader_path: String,
        shader_id: String,
        shader_params: Vec<ParamDesc>,
        /// The light-linking collections it is in (Hydra's categories).
        categories: Vec<String>,
    }

    /// A mesh rprim: its control cage in object space (a holdout).
    #[derive(Clone, Debug, Default)]
    struct MeshDesc {
        path: String,
        xform: [f64; 16],
        points: Vec<f64>,
        face_counts: Vec<i32>,
        face_indices: Vec<i32>,
        hole_indices: Vec<i32>,
        double_sided: bool,
        /// The light-linking collections it is in (Hydra's categories).
        categories: Vec<String>,
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
