#include "prims.h"
#include "convert.h"
#include "renderParam.h"

#include "pxr/base/gf/vec3f.h"
#include "pxr/base/tf/diagnostic.h"
#include "pxr/imaging/hd/material.h"
#include "pxr/imaging/hd/meshTopology.h"
#include "pxr/imaging/hd/sceneDelegate.h"
#include "pxr/imaging/hd/timeSampleArray.h"
#include "pxr/imaging/hd/tokens.h"

PXR_NAMESPACE_OPEN_SCOPE

// ----- transform samples ----------------------------------------------------------

rust::Vec<nimbus_hydra::XformSample> HdNimbusSampleTransform(HdSceneDelegate *delegate,
                                                             SdfPath const &id) {
    // The fixed-capacity form (24.05 has no overload taking the shutter interval);
    // it grows to all the samples the scene delegate has.
    HdTimeSampleArray<GfMatrix4d, 4> samples;
    delegate->SampleTransform(id, &samples);
    rust::Vec<nimbus_hydra::XformSample> out;
    for (size_t i = 0; i < samples.count; ++i) {
        nimbus_hydra::XformSample s;
        s.time = double(samples.times[i]);
        s.xform = HdNimbusMatrix(samples.values[i]);
        out.push_back(std::move(s));
    }
    return out;
}

// ----- camera ---------------------------------------------------------------------

void HdNimbusCamera::Sync(HdSceneDelegate *delegate, HdRenderParam *param,
                          HdDirtyBits *dirtyBits) {
    HdDirtyBits const bits = *dirtyBits;
    HdCamera::Sync(delegate, param, dirtyBits);  // clears the bits
    if (bits & DirtyTransform) _samples = HdNimbusSampleTransform(delegate, GetId());
}

// ----- render settings ------------------------------------------------------------

void HdNimbusRenderSettings::_Sync(HdSceneDelegate *delegate, HdRenderParam *param,
                                   HdDirtyBits const *dirtyBits) {
    VtValue const &v = GetShutterInterval();
    std::vector<double> n = HdNimbusNumbers(v);
    std::array<double, 2> shutter = {0.0, 0.0};
    if (n.size() == 2) shutter = {n[0], n[1]};
    HdNimbusStore(param).SetRenderSettings(GetId(), IsActive(), n.size() == 2, shutter);
}

void HdNimbusRenderSettings::Finalize(HdRenderParam *param) {
    HdNimbusStore(param).Remove(GetId());
}

// ----- volume ---------------------------------------------------------------------

HdDirtyBits HdNimbusVolume::GetInitialDirtyBitsMask() const {
    return HdChangeTracker::AllSceneDirtyBits;
}

TfTokenVector const &HdNimbusVolume::GetBuiltinPrimvarNames() const {
    static TfTokenVector const none;
    return none;
}

// The light-linking collections an rprim is in (Hydra's categories).
static rust::Vec<rust::String> HdNimbusCategories(HdSceneDelegate *delegate, SdfPath const &id) {
    rust::Vec<rust::String> out;
    for (TfToken const &c : delegate->GetCategories(id)) out.push_back(c.GetString());
    return out;
}

void HdNimbusVolume::Sync(HdSceneDelegate *delegate, HdRenderParam *param,
                          HdDirtyBits *dirtyBits, TfToken const &reprToken) {
    SdfPath const &id = GetId();
    HdNimbusSceneStore &store = HdNimbusStore(param);
    _UpdateVisibility(delegate, dirtyBits);
    if (!IsVisible()) {
        store.Remove(id);
        *dirtyBits &= ~HdChangeTracker::AllSceneDirtyBits;
        return;
    }
    HdNimbusVolumeRecord rec;
    rec.desc.path = id.GetString();
    rec.desc.xform = HdNimbusMatrix(delegate->GetTransform(id));
    rec.desc.xform_samples = HdNimbusSampleTransform(delegate, id);
    for (HdVolumeFieldDescriptor const &f : delegate->GetVolumeFieldDescriptors(id)) {
        nimbus_hydra::FieldDesc d;
        d.name = f.fieldName.GetString();
        d.path = f.fieldId.GetString();
        d.prim_type = f.fieldPrimType.GetString();
        d.index = -1;
        rec.desc.fields.push_back(std::move(d));
        rec.fieldIds.push_back(f.fieldId);
    }
    for (HdPrimvarDescriptor const &pv :
         delegate->GetPrimvarDescriptors(id, HdInterpolationConstant)) {
        rec.desc.primvars.push_back(
            HdNimbusParam(pv.name.GetString(), delegate->Get(id, pv.name)));
    }
    rec.materialId = delegate->GetMaterialId(id);
    rec.desc.categories = HdNimbusCategories(delegate, id);
    store.SetVolume(id, std::move(rec));
    *dirtyBits &= ~HdChangeTracker::AllSceneDirtyBits;
}

void HdNimbusVolume::Finalize(HdRenderParam *param) { HdNimbusStore(param).Remove(GetId()); }

// ----- mesh -----------------------------------------------------------------------

HdDirtyBits HdNimbusMesh::GetInitialDirtyBitsMask() const {
    return HdChangeTracker::AllSceneDirtyBits;
}

TfTokenVector const &HdNimbusMesh::GetBuiltinPrimvarNames() const {
    static TfTokenVector const names = {HdTokens->points};
    return names;
}

void HdNimbusMesh::Sync(HdSceneDelegate *delegate, HdRenderParam *param,
                        HdDirtyBits *dirtyBits, TfToken const &reprToken) {
    SdfPath const &id = GetId();
    HdNimbusSceneStore &store = HdNimbusStore(param);
    _UpdateVisibility(delegate, dirtyBits);
    if (!IsVisible()) {
        store.Remove(id);
        *dirtyBits &= ~HdChangeTracker::AllSceneDirtyBits;
        return;
    }
    HdNimbusMeshRecord rec;
    nimbus_hydra::MeshDesc &d = rec.desc;
    d.path = id.GetString();
    d.xform = HdNimbusMatrix(delegate->GetTransform(id));
    d.xform_samples = HdNimbusSampleTransform(delegate, id);
    HdMeshTopology topology = GetMeshTopology(delegate);
    for (int c : topology.GetFaceVertexCounts()) d.face_counts.push_back(c);
    for (int i : topology.GetFaceVertexIndices()) d.face_indices.push_back(i);
    for (int h : topology.GetHoleIndices()) d.hole_indices.push_back(h);
    d.left_handed = topology.GetOrientation() == HdTokens->leftHanded;
    VtValue points = delegate->Get(id, HdTokens->points);
    if (points.IsHolding<VtVec3fArray>()) {
        for (GfVec3f const &p : points.UncheckedGet<VtVec3fArray>()) {
            d.points.push_back(p[0]);
            d.points.push_back(p[1]);
            d.points.push_back(p[2]);
        }
    } else if (!points.IsEmpty()) {
        TF_WARN("hdNimbus: mesh %s: points of type %s are not read; the mesh is left out",
                id.GetText(), points.GetTypeName().c_str());
        store.Remove(id);
        *dirtyBits &= ~HdChangeTracker::AllSceneDirtyBits;
        return;
    }
    d.double_sided = delegate->GetDoubleSided(id);
    d.categories = HdNimbusCategories(delegate, id);
    // NimbusVolumeAPI's `nimbus:*` primvars and the material make it a fog box (Rust
    // decides: scene.rs).
    for (HdPrimvarDescriptor const &pv :
         delegate->GetPrimvarDescriptors(id, HdInterpolationConstant)) {
        d.primvars.push_back(HdNimbusParam(pv.name.GetString(), delegate->Get(id, pv.name)));
    }
    rec.materialId = delegate->GetMaterialId(id);
    store.SetMesh(id, std::move(rec));
    *dirtyBits &= ~HdChangeTracker::AllSceneDirtyBits;
}

void HdNimbusMesh::Finalize(HdRenderParam *param) { HdNimbusStore(param).Remove(GetId()); }

// ----- light ----------------------------------------------------------------------

// A light parameter by Hydra's name, or by its UsdLux input name (`inputs:NAME`):
// scene delegates answer with one or the other.
static VtValue _LightParam(HdSceneDelegate *delegate, SdfPath const &id, TfToken const &name) {
    VtValue v = delegate->GetLightParamValue(id, name);
    if (v.IsEmpty()) v = delegate->GetLightParamValue(id, TfToken("inputs:" + name.GetString()));
    return v;
}

void HdNimbusLight::Sync(HdSceneDelegate *delegate, HdRenderParam *param,
                         HdDirtyBits *dirtyBits) {
    SdfPath const &id = GetId();
    HdNimbusSceneStore &store = HdNimbusStore(param);
    static TfToken const supported[] = {
        HdPrimTypeTokens->sphereLight, HdPrimTypeTokens->distantLight,
        HdPrimTypeTokens->rectLight,   HdPrimTypeTokens->diskLight,
        HdPrimTypeTokens->cylinderLight, HdPrimTypeTokens->domeLight};
    bool known = false;
    for (TfToken const &t : supported) known = known || t == _type;
    if (!known) {
        store.SetUnsupportedLight(id, _type.GetString());
        *dirtyBits = Clean;
        return;
    }
    auto P = [&](TfToken const &name) { return _LightParam(delegate, id, name); };
    auto N = [&](TfToken const &name, double fallback) { return HdNimbusNumber(P(name), fallback); };
    auto B = [&](TfToken const &name, bool fallback) { return HdNimbusBool(P(name), fallback); };
    auto const &t = *HdLightTokens;
    nimbus_hydra::LightDesc d;
    d.kind = _type.GetString();
    d.path = id.GetString();
    d.xform = HdNimbusMatrix(delegate->GetTransform(id));
    d.xform_samples = HdNimbusSampleTransform(delegate, id);
    // Visibility off (a hidden light) removes it.
    if (!delegate->GetVisible(id)) {
        store.Remove(id);
        *dirtyBits = Clean;
        return;
    }
    // UsdLux's fallbacks.
    d.intensity = N(t.intensity, 1.0);
    d.exposure = N(t.exposure, 0.0);
    std::vector<double> c = HdNimbusNumbers(P(t.color));
    d.color = c.size() >= 3 ? std::array<double, 3>{c[0], c[1], c[2]}
                            : std::array<double, 3>{1.0, 1.0, 1.0};
    d.normalize = B(t.normalize, false);
    d.enable_color_temperature = B(t.enableColorTemperature, false);
    d.color_temperature = N(t.colorTemperature, 6500.0);
    d.radius = N(t.radius, 0.5);
    d.width = N(t.width, 1.0);
    d.height = N(t.height, 1.0);
    d.length = N(t.length, 1.0);
    d.angle = N(t.angle, 0.53);
    d.treat_as_point = B(TfToken("treatAsPoint"), false);
    d.treat_as_line = B(TfToken("treatAsLine"), false);
    d.lights_interior = B(TfToken("nimbus:lightsInterior"), false);
    d.diffuse = N(t.diffuse, 1.0);
    d.texture_file = HdNimbusText(P(t.textureFile));
    d.texture_format = HdNimbusText(P(t.textureFormat));
    d.shadow_enable = B(t.shadowEnable, true);
    VtValue cone = P(t.shapingConeAngle), focus = P(t.shapingFocus),
            softness = P(t.shapingConeSoftness), ies = P(t.shapingIesFile);
    d.has_shaping = !cone.IsEmpty() || !focus.IsEmpty() || !softness.IsEmpty() ||
                    !HdNimbusText(ies).empty();
    d.shaping_focus = HdNimbusNumber(focus, 0.0);
    std::vector<double> tint = HdNimbusNumbers(P(t.shapingFocusTint));
    d.shaping_focus_tint = tint.size() >= 3 ? std::array<double, 3>{tint[0], tint[1], tint[2]}
                                            : std::array<double, 3>{0.0, 0.0, 0.0};
    d.shaping_cone_angle = HdNimbusNumber(cone, 90.0);
    d.shaping_cone_softness = HdNimbusNumber(softness, 0.0);
    d.shaping_ies_file = HdNimbusText(ies);
    d.shaping_ies_angle_scale = N(t.shapingIesAngleScale, 0.0);
    d.shaping_ies_normalize = B(t.shapingIesNormalize, false);
    d.light_group = HdNimbusText(delegate->GetLightParamValue(id, TfToken("nimbus:lightGroup")));
    // The linking collections by name (empty: everything); the rprims list the
    // collections they are in as their categories.
    d.light_link = HdNimbusText(delegate->GetLightParamValue(id, HdTokens->lightLink));
    d.shadow_link = HdNimbusText(delegate->GetLightParamValue(id, HdTokens->shadowLink));
    store.SetLight(id, std::move(d));
    *dirtyBits = Clean;
}

void HdNimbusLight::Finalize(HdRenderParam *param) { HdNimbusStore(param).Remove(GetId()); }

// ----- field ----------------------------------------------------------------------

void HdNimbusField::Sync(HdSceneDelegate *delegate, HdRenderParam *param,
                         HdDirtyBits *dirtyBits) {
    SdfPath const &id = GetId();
    nimbus_hydra::FieldDesc d;
    d.path = id.GetString();
    d.prim_type = _type.GetString();
    d.file = HdNimbusText(delegate->Get(id, HdFieldTokens->filePath));
    d.grid = HdNimbusText(delegate->Get(id, HdFieldTokens->fieldName));
    d.index = int(HdNimbusNumber(delegate->Get(id, TfToken("fieldIndex")), -1.0));
    HdNimbusStore(param).SetField(id, std::move(d));
    *dirtyBits = Clean;
}

void HdNimbusField::Finalize(HdRenderParam *param) { HdNimbusStore(param).Remove(GetId()); }

// ----- material -------------------------------------------------------------------

void HdNimbusMaterial::Sync(HdSceneDelegate *delegate, HdRenderParam *param,
                            HdDirtyBits *dirtyBits) {
    SdfPath const &id = GetId();
    HdNimbusMaterialRecord rec;
    VtValue resource = delegate->GetMaterialResource(id);
    if (resource.IsHolding<HdMaterialNetworkMap>()) {
        HdMaterialNetworkMap const &map = resource.UncheckedGet<HdMaterialNetworkMap>();
        // The volume shader Nimbus reads, wherever it sits in the networks; else the
        // volume terminal's first node (named in the warning).
        auto take = [&rec](HdMaterialNode const &node) {
            rec.shaderPath = node.path.GetString();
            rec.shaderId = node.identifier.GetString();
            rec.params.clear();
            for (auto const &p : node.parameters) {
                rec.params.push_back(HdNimbusParam(p.first.GetString(), p.second));
            }
        };
        // Every node, for a density graph driving the shader's inputs: parameters,
        // and the relationships into it as connected inputs.
        for (auto const &net : map.map) {
            for (HdMaterialNode const &node : net.second.nodes) {
                nimbus_hydra::ShaderNodeDesc n;
                n.path = node.path.GetString();
                n.id = node.identifier.GetString();
                for (auto const &p : node.parameters) {
                    n.params.push_back(HdNimbusParam(p.first.GetString(), p.second));
                }
                for (HdMaterialRelationship const &r : net.second.relationships) {
                    if (r.outputId != node.path) continue;
                    nimbus_hydra::ConnectionDesc c;
                    c.input = r.outputName.GetString();
                    c.node = r.inputId.GetString();
                    c.output = r.inputName.GetString();
                    n.connections.push_back(std::move(c));
                }
                rec.network.push_back(std::move(n));
            }
        }
        bool found = false;
        for (auto const &net : map.map) {
            for (HdMaterialNode const &node : net.second.nodes) {
                std::string const &nid = node.identifier.GetString();
                if (!found && (nid == "PxrVolume" || nid == "ND_anisotropic_vdf")) {
                    take(node);
                    found = true;
                } else if (!found && rec.shaderId.empty() &&
                           net.first == HdMaterialTerminalTokens->volume) {
                    take(node);
                }
            }
        }
    }
    HdNimbusStore(param).SetMaterial(id, std::move(rec));
    *dirtyBits = Clean;
}

void HdNimbusMaterial::Finalize(HdRenderParam *param) { HdNimbusStore(param).Remove(GetId()); }

PXR_NAMESPACE_CLOSE_SCOPE
