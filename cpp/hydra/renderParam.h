// What hdNimbus' render delegate shares with its prims and render passes, as hdEmbree's
// HdEmbreeRenderParam does: the scene store the prims' Syncs fill, the progress the
// render passes report for the delegate's statistics, and the render passes alive. The
// delegate owns it; a render pass is handed pointers to the parts it uses (as
// HdEmbreeRenderPass is handed the renderer and the scene version), so it never needs
// the delegate's class.
#ifndef HDNIMBUS_RENDER_PARAM_H
#define HDNIMBUS_RENDER_PARAM_H

#include "pxr/pxr.h"
#include "pxr/imaging/hd/renderDelegate.h"

#include "convert.h"

#include <mutex>
#include <set>

PXR_NAMESPACE_OPEN_SCOPE

class HdNimbusRenderPass;

// Where the latest render stands: written by a render thread after each pass, read by
// the host's GetRenderStats on its own thread.
class HdNimbusProgress {
public:
    void Set(nimbus_hydra::PassInfo const &info) {
        std::lock_guard<std::mutex> lock(_mutex);
        _info = info;
    }
    nimbus_hydra::PassInfo Get() const {
        std::lock_guard<std::mutex> lock(_mutex);
        return _info;
    }

private:
    mutable std::mutex _mutex;
    nimbus_hydra::PassInfo _info;
};

// The render passes alive, so a render buffer about to be destroyed is first let go by
// any render thread writing it. A pass adds itself when made and removes itself first
// thing when destroyed; ForEach holds the lock, so no pass it visits is destroyed
// meanwhile.
class HdNimbusRenderPasses {
public:
    void Add(HdNimbusRenderPass *pass) {
        std::lock_guard<std::mutex> lock(_mutex);
        _passes.insert(pass);
    }
    void Remove(HdNimbusRenderPass *pass) {
        std::lock_guard<std::mutex> lock(_mutex);
        _passes.erase(pass);
    }
    template <class F> void ForEach(F &&f) {
        std::lock_guard<std::mutex> lock(_mutex);
        for (HdNimbusRenderPass *pass : _passes) f(pass);
    }

private:
    std::mutex _mutex;
    std::set<HdNimbusRenderPass *> _passes;
};

// The render param every prim's Sync receives (it uses the store).
class HdNimbusRenderParam final : public HdRenderParam {
public:
    HdNimbusSceneStore store;
    HdNimbusProgress progress;
    HdNimbusRenderPasses passes;
};

inline HdNimbusSceneStore &HdNimbusStore(HdRenderParam *p) {
    return static_cast<HdNimbusRenderParam *>(p)->store;
}

PXR_NAMESPACE_CLOSE_SCOPE

#endif
