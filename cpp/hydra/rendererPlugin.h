// hdNimbus' renderer plugin: what Hydra's plugin registry finds through plugInfo.json.
#ifndef HDNIMBUS_RENDERER_PLUGIN_H
#define HDNIMBUS_RENDERER_PLUGIN_H

#include "pxr/pxr.h"
#include "pxr/imaging/hd/rendererPlugin.h"

PXR_NAMESPACE_OPEN_SCOPE

class HdNimbusRendererPlugin final : public HdRendererPlugin {
public:
    HdNimbusRendererPlugin() = default;
    ~HdNimbusRendererPlugin() override = default;
    HdRenderDelegate *CreateRenderDelegate() override;
    HdRenderDelegate *CreateRenderDelegate(HdRenderSettingsMap const &settings) override;
    void DeleteRenderDelegate(HdRenderDelegate *delegate) override;
    // A CPU renderer: supported with or without a GPU.
    bool IsSupported(bool gpuEnabled = true) const override { return true; }
};

PXR_NAMESPACE_CLOSE_SCOPE

#endif
