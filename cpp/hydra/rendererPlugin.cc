#include "rendererPlugin.h"
#include "renderDelegate.h"

#include "pxr/imaging/hd/rendererPluginRegistry.h"

PXR_NAMESPACE_OPEN_SCOPE

TF_REGISTRY_FUNCTION(TfType) {
    HdRendererPluginRegistry::Define<HdNimbusRendererPlugin>();
}

HdRenderDelegate *HdNimbusRendererPlugin::CreateRenderDelegate() {
    return new HdNimbusRenderDelegate();
}

HdRenderDelegate *
HdNimbusRendererPlugin::CreateRenderDelegate(HdRenderSettingsMap const &settings) {
    return new HdNimbusRenderDelegate(settings);
}

void HdNimbusRendererPlugin::DeleteRenderDelegate(HdRenderDelegate *delegate) {
    delete delegate;
}

PXR_NAMESPACE_CLOSE_SCOPE
