//! What a stage authors, besides lights, that changes a render and that Nimbus does not
//! read: each becomes a stage warning ([`Diagnostics`]) naming the prim and, where there
//! is one, the attribute or relationship, so the render never differs from the stage
//! without a word (unsupported lights are warned about in `stage.rs`).
//!
//! - gprims Nimbus cannot turn into holdouts (`Points`, `BasisCurves`, `NurbsCurves`,
//!   `NurbsPatch`, …) that would occlude: visible, `default` or `render` purpose,
//!   `nimbus:holdout` not false;
//! - `PointInstancer`s: their instances are not placed, so they occlude nothing;
//! - a volume's `field:*` relationship to a field type other than `OpenVDBAsset`
//!   (`Field3DAsset`): the field is left out;
//! - a material bound to a volume that has no volume output Nimbus reads: the volume
//!   takes its medium from the `nimbus:*` attributes and the schema's fallbacks;
//! - render settings and products (UsdRenderSettingsBase) asking for what the render
//!   does not do: `pixelAspectRatio` other than 1, `dataWindowNDC` other than the whole
//!   frame, `aspectRatioConformPolicy` other than `expandAperture`, a product's own
//!   `resolution`.
//!
//! The loader decides which prims are candidates; this module reads the attribute that
//! says the render would differ and words the warning.

use super::attrs::*;
use super::diagnostics::Diagnostics;
use openusd::sdf::Value;
use openusd::usd::{Prim, TimeCode};

/// The prim's type name, or "untyped prim".
fn type_name(prim: &Prim) -> Result<String, SceneError> {
    Ok(prim
        .type_name()
        .map_err(|e| prim_error(prim.path(), e))?
        .map(|t| t.to_string())
        .filter(|t| !t.is_empty())
        .unwrap_or_else(|| "untyped prim".to_string()))
}

/// A gprim that would occlude (the loader checked visibility, purpose and
/// `nimbus:holdout`) but that Nimbus has no tessellation for.
pub(super) fn unread_gprim(prim: &Prim, warnings: &mut Diagnostics) -> Result<(), SceneError> {
    let ty = type_name(prim)?;
    warnings.warn(
        format!("{ty} holdout"),
        prim.path().to_string(),
        None,
        format!(
            "{ty} prims are not read as holdouts: this one does not occlude the volumes \
             (set nimbus:holdout = false to say so)"
        ),
    );
    Ok(())
}

/// A PointInstancer with gprims among its prototypes: those are not placed (its
/// volume prototypes are).
pub(super) fn point_instancer(prim: &Prim, gprims: usize, warnings: &mut Diagnostics) {
    warnings.warn(
        "PointInstancer",
        prim.path().to_string(),
        Some("prototypes"),
        format!(
            "{gprims} gprims beneath its prototypes are not placed (only volume prototypes are instanced): their instances do not occlude or fill"
        ),
    );
}

/// A volume's field relationship `rel` targets `field`, which is not an OpenVDBAsset.
pub(super) fn unread_field(
    volume: &Prim,
    rel: &str,
    field: &Prim,
    warnings: &mut Diagnostics,
) -> Result<(), SceneError> {
    let ty = type_name(field)?;
    warnings.warn(
        format!("{ty} field"),
        volume.path().to_string(),
        Some(rel),
        format!(
            "targets {} ({ty}); Nimbus reads OpenVDBAsset fields only: this field is left out",
            field.path()
        ),
    );
    Ok(())
}

/// A material bound to `volume` that has no volume output Nimbus reads.
pub(super) fn unread_material(volume: &Prim, material: &str, warnings: &mut Diagnostics) {
    warnings.warn(
        "volume material",
        volume.path().to_string(),
        Some("material:binding"),
        format!(
            "the bound material {material} has no volume output Nimbus reads \
             (outputs:volume, outputs:mtlx:volume, …): the volume takes its medium \
             from its nimbus:* attributes and the schema's fallbacks"
        ),
    );
}

/// The UsdRenderSettingsBase attributes of a RenderSettings (`product` false) or
/// RenderProduct prim that ask for what the render does not do.
pub(super) fn render_settings_base(
    prim: &Prim,
    product: bool,
    time: Option<TimeCode>,
    warnings: &mut Diagnostics,
) -> Result<(), SceneError> {
    let path = prim.path().to_string();
    if let Some(ratio) = read_f64(prim, "pixelAspectRatio", time)? {
        if ratio != 1.0 {
            warnings.warn(
                "pixelAspectRatio",
                path.clone(),
                Some("pixelAspectRatio"),
                format!("is {ratio}: Nimbus renders square pixels"),
            );
        }
    }
    if let Some(window) = read_vec4(prim, "dataWindowNDC", time)? {
        if window != [0.0, 0.0, 1.0, 1.0] {
            warnings.warn(
                "dataWindowNDC",
                path.clone(),
                Some("dataWindowNDC"),
                format!("is {window:?}: Nimbus renders the whole frame (use --region or --tile)"),
            );
        }
    }
    if let Some(policy) = read_string(prim, "aspectRatioConformPolicy", time)? {
        if policy != "expandAperture" {
            warnings.warn(
                "aspectRatioConformPolicy",
                path.clone(),
                Some("aspectRatioConformPolicy"),
                format!("is `{policy}`: Nimbus conforms the camera with `expandAperture`"),
            );
        }
    }
    // A product's `resolution` has the schema's fallback (2048 × 1080): only an
    // authored one asks for something.
    if product && authored(&prim.attribute("resolution"), prim)? {
        warnings.warn(
            "RenderProduct resolution",
            path,
            Some("resolution"),
            "a product's own resolution is not read: every product has the render \
             settings' resolution (or --res)",
        );
    }
    Ok(())
}

/// A float4 attribute (`dataWindowNDC`), when it has a value.
fn read_vec4(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<[f64; 4]>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Vec4f(v) => Ok(Some([v.x, v.y, v.z, v.w].map(f64::from))),
        Value::Vec4d(v) => Ok(Some([v.x, v.y, v.z, v.w])),
        other => Err(wrong_type(prim, name, "a float4", &other)),
    }
}
