// hdNimbus' render pass. An Execute that finds the scene, the settings, the camera or
// the AOV bindings changed stops the render thread, hands the new scene to the Rust
// renderer and starts the thread again; the thread renders pass after pass (each one
// more batch of samples per pixel, the schedule `nimbus render` uses), writes the
// buffers after each, and ends when the sample count is reached. Hosts poll
// IsConverged and the buffers (Blender's final render calls Execute once).
//
// Shaped as hdEmbree's HdEmbreeRenderPass: it is handed what it uses (its Rust
// renderer, the scene store, the settings, where to report progress, the set of live
// passes) and never sees the render delegate, which includes this header.
#ifndef HDNIMBUS_RENDER_PASS_H
#define HDNIMBUS_RENDER_PASS_H

#include "pxr/pxr.h"
#include "pxr/imaging/hd/renderDelegate.h"
#include "pxr/imaging/hd/renderPass.h"

#include "nimbus-hydra/src/ffi.rs.h"

#include <atomic>
#include <thread>
#include <vector>

PXR_NAMESPACE_OPEN_SCOPE

class HdNimbusSceneStore;
class HdNimbusProgress;
class HdNimbusRenderPasses;
class HdNimbusRenderBuffer;

class HdNimbusRenderPass final : public HdRenderPass {
public:
    // `store` is what the prims synced; `settings` the delegate's render settings
    // (their version is the delegate's, read through the render index); the pass
    // reports each pass to `progress` and is in `passes` while it lives. All of them
    // outlive the pass (the delegate owns them).
    HdNimbusRenderPass(HdRenderIndex *index, HdRprimCollection const &collection,
                       rust::Box<nimbus_hydra::Renderer> renderer,
                       HdNimbusSceneStore const *store, HdRenderSettingsMap const *settings,
                       HdNimbusProgress *progress, HdNimbusRenderPasses *passes);
    ~HdNimbusRenderPass() override;
    bool IsConverged() const override { return _converged.load(); }
    // Stops the render thread if it writes `buffer` (about to be destroyed); the next
    // Execute starts again with the bindings it is given.
    void Release(HdNimbusRenderBuffer *buffer);

protected:
    void _Execute(HdRenderPassStateSharedPtr const &state,
                  TfTokenVector const &renderTags) override;

private:
    void _Stop();
    void _Run();
    // Copies the renderer's AOVs into the bound buffers.
    void _WriteBuffers();

    rust::Box<nimbus_hydra::Renderer> _renderer;
    HdNimbusSceneStore const *_store;
    HdRenderSettingsMap const *_settings;
    HdNimbusProgress *_progress;
    HdNimbusRenderPasses *_passes;
    // What the running render was started from: the store's version, the settings'
    // version, the camera and the image size.
    uint64_t _sceneVersion = 0;
    unsigned int _settingsVersion = 0;
    std::vector<double> _cameraKey;
    std::vector<std::pair<TfToken, HdNimbusRenderBuffer *>> _buffers;
    std::thread _thread;
    std::atomic<bool> _stop{false};
    std::atomic<bool> _converged{false};
    bool _started = false;
};

PXR_NAMESPACE_CLOSE_SCOPE

#endif
