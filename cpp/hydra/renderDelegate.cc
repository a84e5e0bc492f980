#include "renderDelegate.h"
#include "prims.h"
#include "renderBuffer.h"
#include "renderPass.h"

#include "pxr/base/gf/vec3f.h"
#include "pxr/base/gf/vec4f.h"
#include "pxr/base/tf/diagnostic.h"
#include "pxr/imaging/hd/camera.h"
#include "pxr/imaging/hd/instancer.h"
#include "pxr/imaging/hd/tokens.h"

PXR_NAMESPACE_OPEN_SCOPE

// Field bprim types: openvdbAsset is read; field3dAsset is accepted so a volume naming
// one fails with a message instead of losing the field silently.
static TfToken const &_OpenVdbAsset() {
    static TfToken const t("openvdbAsset");
    return t;
}
static TfToken const &_Field3dAsset() {
    static TfToken const t("field3dAsset");
    return t;
}

HdNimbusRenderDelegate::HdNimbusRenderDelegate() { _Init(); }

HdNimbusRenderDelegate::HdNimbusRenderDelegate(HdRenderSettingsMap const &settings)
    : HdRenderDelegate(settings) {
    _Init();
}

void HdNimbusRenderDelegate::_Init() {
    _param = std::make_unique<HdNimbusRenderParam>();
    _registry = std::make_shared<HdResourceRegistry>();
    // The descriptors' defaults are not put into the settings: only what the host sets
    // reaches the renderer, as only what a stage authors does (an authored
    // nimbus:octreeDepth, even 0, keeps `auto` from choosing the majorants).
}

TfTokenVector const &HdNimbusRenderDelegate::GetSupportedRprimTypes() const {
    static TfTokenVector const types = {HdPrimTypeTokens->volume, HdPrimTypeTokens->mesh};
    return types;
}

TfTokenVector const &HdNimbusRenderDelegate::GetSupportedSprimTypes() const {
    // Every light type: the ones the core lacks are synced to be warned about.
    static TfTokenVector const types = [] {
        TfTokenVector t = {HdPrimTypeTokens->camera, HdPrimTypeTokens->material};
        for (TfToken const &l : HdLightPrimTypeTokens()) t.push_back(l);
        return t;
    }();
    return types;
}

TfTokenVector const &HdNimbusRenderDelegate::GetSupportedBprimTypes() const {
    static TfTokenVector const types = {HdPrimTypeTokens->renderBuffer, _OpenVdbAsset(),
                                        _Field3dAsset(), HdPrimTypeTokens->renderSettings};
    return types;
}

HdRenderSettingDescriptorList HdNimbusRenderDelegate::GetRenderSettingDescriptors() const {
    HdRenderSettingDescriptorList out;
    for (nimbus_hydra::SettingDescriptor const &d : nimbus_hydra::setting_descriptors()) {
        HdRenderSettingDescriptor h;
        h.name = std::string(d.name);
        h.key = TfToken(std::string(d.key));
        if (d.is_text) {
            h.defaultValue = VtValue(TfToken(std::string(d.text)));
        } else if (d.is_int) {
            h.defaultValue = VtValue(int(d.number));
        } else {
            h.defaultValue = VtValue(d.number);
        }
        out.push_back(h);
    }
    return out;
}

VtDictionary HdNimbusRenderDelegate::GetRenderStats() const {
    nimbus_hydra::PassInfo const progress = _param->progress.Get();
    VtDictionary d;
    double done = progress.target_spp ? 100.0 * progress.spp / progress.target_spp : 0.0;
    d["percentDone"] = VtValue(done);
    d["totalClockTime"] = VtValue(progress.seconds);
    d["nimbus:spp"] = VtValue(int(progress.spp));
    d["nimbus:lookupsPerSample"] = VtValue(progress.lookups_per_sample);
    return d;
}

HdAovDescriptor HdNimbusRenderDelegate::GetDefaultAovDescriptor(TfToken const &name) const {
    if (name == HdAovTokens->color) {
        return HdAovDescriptor(HdFormatFloat32Vec4, false, VtValue(GfVec4f(0.0f)));
    }
    if (name == HdAovTokens->depth) {
        return HdAovDescriptor(HdFormatFloat32, false, VtValue(1.0f));
    }
    if (nimbus_hydra::is_split_aov(name.GetString())) {
        // A light group or path split: an RGB part of the beauty.
        return HdAovDescriptor(HdFormatFloat32Vec3, false, VtValue(GfVec3f(0.0f)));
    }
    if (nimbus_hydra::is_aov(name.GetString())) {
        return HdAovDescriptor(HdFormatFloat32, false, VtValue(0.0f));
    }
    return HdAovDescriptor();
}

HdRenderPassSharedPtr
HdNimbusRenderDelegate::CreateRenderPass(HdRenderIndex *index,
                                         HdRprimCollection const &collection) {
    // The pass gets what it uses, not the delegate (as hdEmbree's): its own Rust
    // renderer, the store it snapshots, the settings it hands over, where it reports
    // progress, and the set it joins so DestroyBprim can take a buffer from it.
    return std::make_shared<HdNimbusRenderPass>(index, collection, nimbus_hydra::new_renderer(),
                                                &_param->store, &_settingsMap,
                                                &_param->progress, &_param->passes);
}

HdInstancer *HdNimbusRenderDelegate::CreateInstancer(HdSceneDelegate *delegate,
                                                     SdfPath const &id) {
    TF_WARN("hdNimbus: instancer %s: instancing is not rendered", id.GetText());
    return new HdInstancer(delegate, id);
}

void HdNimbusRenderDelegate::DestroyInstancer(HdInstancer *instancer) { delete instancer; }

HdRprim *HdNimbusRenderDelegate::CreateRprim(TfToken const &typeId, SdfPath const &id) {
    if (typeId == HdPrimTypeTokens->volume) return new HdNimbusVolume(id);
    if (typeId == HdPrimTypeTokens->mesh) return new HdNimbusMesh(id);
    TF_CODING_ERROR("hdNimbus: unknown rprim type %s", typeId.GetText());
    return nullptr;
}

void HdNimbusRenderDelegate::DestroyRprim(HdRprim *rprim) {
    if (rprim) Store().Remove(rprim->GetId());
    delete rprim;
}

HdSprim *HdNimbusRenderDelegate::CreateSprim(TfToken const &typeId, SdfPath const &id) {
    if (typeId == HdPrimTypeTokens->camera) return new HdNimbusCamera(id);
    if (typeId == HdPrimTypeTokens->material) return new HdNimbusMaterial(id);
    if (HdPrimTypeIsLight(typeId)) return new HdNimbusLight(id, typeId);
    TF_CODING_ERROR("hdNimbus: unknown sprim type %s", typeId.GetText());
    return nullptr;
}

HdSprim *HdNimbusRenderDelegate::CreateFallbackSprim(TfToken const &typeId) {
    return CreateSprim(typeId, SdfPath::EmptyPath());
}

void HdNimbusRenderDelegate::DestroySprim(HdSprim *sprim) {
    if (sprim) Store().Remove(sprim->GetId());
    delete sprim;
}

HdBprim *HdNimbusRenderDelegate::CreateBprim(TfToken const &typeId, SdfPath const &id) {
    if (typeId == HdPrimTypeTokens->renderBuffer) return new HdNimbusRenderBuffer(id);
    if (typeId == _OpenVdbAsset() || typeId == _Field3dAsset()) return new HdNimbusField(id, typeId);
    if (typeId == HdPrimTypeTokens->renderSettings) return new HdNimbusRenderSettings(id);
    TF_CODING_ERROR("hdNimbus: unknown bprim type %s", typeId.GetText());
    return nullptr;
}

HdBprim *HdNimbusRenderDelegate::CreateFallbackBprim(TfToken const &typeId) {
    return CreateBprim(typeId, SdfPath::EmptyPath());
}

void HdNimbusRenderDelegate::DestroyBprim(HdBprim *bprim) {
    if (auto *rb = dynamic_cast<HdNimbusRenderBuffer *>(bprim)) {
        _param->passes.ForEach([rb](HdNimbusRenderPass *pass) { pass->Release(rb); });
    }
    if (bprim) Store().Remove(bprim->GetId());
    delete bprim;
}

PXR_NAMESPACE_CLOSE_SCOPE
