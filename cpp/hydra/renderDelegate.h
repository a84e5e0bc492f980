// hdNimbus' render delegate: the prim types it supports, the store its prims sync
// into, its render settings and statistics.
#ifndef HDNIMBUS_RENDER_DELEGATE_H
#define HDNIMBUS_RENDER_DELEGATE_H

#include "pxr/pxr.h"
#include "pxr/imaging/hd/renderDelegate.h"
#include "pxr/imaging/hd/resourceRegistry.h"

#include "renderParam.h"

PXR_NAMESPACE_OPEN_SCOPE

class HdNimbusRenderDelegate final : public HdRenderDelegate {
public:
    HdNimbusRenderDelegate();
    explicit HdNimbusRenderDelegate(HdRenderSettingsMap const &settings);
    ~HdNimbusRenderDelegate() override = default;

    TfTokenVector const &GetSupportedRprimTypes() const override;
    TfTokenVector const &GetSupportedSprimTypes() const override;
    TfTokenVector const &GetSupportedBprimTypes() const override;
    HdResourceRegistrySharedPtr GetResourceRegistry() const override { return _registry; }
    HdRenderParam *GetRenderParam() const override { return _param.get(); }
    HdRenderSettingDescriptorList GetRenderSettingDescriptors() const override;
    VtDictionary GetRenderStats() const override;

    HdRenderPassSharedPtr CreateRenderPass(HdRenderIndex *index,
                                           HdRprimCollection const &collection) override;
    HdInstancer *CreateInstancer(HdSceneDelegate *delegate, SdfPath const &id) override;
    void DestroyInstancer(HdInstancer *instancer) override;
    HdRprim *CreateRprim(TfToken const &typeId, SdfPath const &rprimId) override;
    void DestroyRprim(HdRprim *rprim) override;
    HdSprim *CreateSprim(TfToken const &typeId, SdfPath const &sprimId) override;
    HdSprim *CreateFallbackSprim(TfToken const &typeId) override;
    void DestroySprim(HdSprim *sprim) override;
    HdBprim *CreateBprim(TfToken const &typeId, SdfPath const &bprimId) override;
    HdBprim *CreateFallbackBprim(TfToken const &typeId) override;
    void DestroyBprim(HdBprim *bprim) override;
    void CommitResources(HdChangeTracker *tracker) override {}
    HdAovDescriptor GetDefaultAovDescriptor(TfToken const &name) const override;

    HdNimbusSceneStore &Store() { return _param->store; }

private:
    void _Init();

    std::unique_ptr<HdNimbusRenderParam> _param;
    HdResourceRegistrySharedPtr _registry;
};

PXR_NAMESPACE_CLOSE_SCOPE

#endif
