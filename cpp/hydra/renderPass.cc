#include "renderPass.h"
#include "convert.h"
#include "prims.h"
#include "renderBuffer.h"
#include "renderParam.h"

#include "pxr/base/tf/diagnostic.h"
#include "pxr/imaging/hd/camera.h"
#include "pxr/imaging/hd/renderIndex.h"
#include "pxr/imaging/hd/renderPassState.h"

#include <cstdio>
#include <exception>

PXR_NAMESPACE_OPEN_SCOPE

HdNimbusRenderPass::HdNimbusRenderPass(HdRenderIndex *index,
                                       HdRprimCollection const &collection,
                                       rust::Box<nimbus_hydra::Renderer> renderer,
                                       HdNimbusSceneStore const *store,
                                       HdRenderSettingsMap const *settings,
                                       HdNimbusProgress *progress, HdNimbusRenderPasses *passes)
    : HdRenderPass(index, collection), _renderer(std::move(renderer)), _store(store),
      _settings(settings), _progress(progress), _passes(passes) {
    _passes->Add(this);
}

// The camera as plain data (Hydra's world units).
static nimbus_hydra::CameraDesc _Camera(HdCamera const *cam) {
    nimbus_hydra::CameraDesc c;
    c.path = cam->GetId().GetString();
    c.xform = HdNimbusMatrix(cam->GetTransform());
    c.orthographic = cam->GetProjection() == HdCamera::Orthographic;
    c.focal_length = cam->GetFocalLength();
    c.horizontal_aperture = cam->GetHorizontalAperture();
    c.vertical_aperture = cam->GetVerticalAperture();
    c.horizontal_aperture_offset = cam->GetHorizontalApertureOffset();
    c.vertical_aperture_offset = cam->GetVerticalApertureOffset();
    c.near = cam->GetClippingRange().GetMin();
    c.far = cam->GetClippingRange().GetMax();
    c.f_stop = cam->GetFStop();
    c.focus_distance = cam->GetFocusDistance();
    c.shutter_open = cam->GetShutterOpen();
    c.shutter_close = cam->GetShutterClose();
    if (auto const *ours = dynamic_cast<HdNimbusCamera const *>(cam)) {
        c.xform_samples = ours->GetTransformSamples();
    }
    return c;
}

static std::vector<double> _CameraKey(nimbus_hydra::CameraDesc const &c, bool has,
                                      unsigned w, unsigned h) {
    std::vector<double> k(c.xform.begin(), c.xform.end());
    double rest[] = {double(has), double(w), double(h), double(c.orthographic),
                     c.focal_length, c.horizontal_aperture, c.vertical_aperture,
                     c.horizontal_aperture_offset, c.vertical_aperture_offset,
                     c.near, c.far, c.f_stop, c.focus_distance,
                     c.shutter_open, c.shutter_close};
    k.insert(k.end(), std::begin(rest), std::end(rest));
    for (nimbus_hydra::XformSample const &s : c.xform_samples) {
        k.push_back(s.time);
        k.insert(k.end(), s.xform.begin(), s.xform.end());
    }
    return k;
}

HdNimbusRenderPass::~HdNimbusRenderPass() {
    _passes->Remove(this);
    _Stop();
}

void HdNimbusRenderPass::Release(HdNimbusRenderBuffer *buffer) {
    for (auto const &b : _buffers) {
        if (b.second != buffer) continue;
        _Stop();
        _buffers.clear();
        _started = false;
        return;
    }
}

void HdNimbusRenderPass::_Stop() {
    _stop.store(true);
    if (_thread.joinable()) _thread.join();
    _stop.store(false);
}

void HdNimbusRenderPass::_Execute(HdRenderPassStateSharedPtr const &state,
                                  TfTokenVector const &renderTags) {
    // The buffers to fill and the image size (the first buffer's).
    std::vector<std::pair<TfToken, HdNimbusRenderBuffer *>> buffers;
    for (HdRenderPassAovBinding const &b : state->GetAovBindings()) {
        HdRenderBuffer *rb = b.renderBuffer;
        if (!rb) {
            rb = static_cast<HdRenderBuffer *>(GetRenderIndex()->GetBprim(
                HdPrimTypeTokens->renderBuffer, b.renderBufferId));
        }
        if (auto *nb = dynamic_cast<HdNimbusRenderBuffer *>(rb)) {
            buffers.emplace_back(b.aovName, nb);
        }
    }
    if (buffers.empty()) {
        _Stop();
        _converged.store(true);
        return;
    }
    unsigned w = buffers[0].second->GetWidth(), h = buffers[0].second->GetHeight();

    HdCamera const *cam = state->GetCamera();
    nimbus_hydra::CameraDesc camera;
    if (cam) camera = _Camera(cam);
    std::vector<double> key = _CameraKey(camera, cam != nullptr, w, h);
    uint64_t version = _store->Version();
    unsigned settings = GetRenderIndex()->GetRenderDelegate()->GetRenderSettingsVersion();
    if (_started && version == _sceneVersion && settings == _settingsVersion &&
        key == _cameraKey && buffers == _buffers) {
        return;  // the render thread goes on (or has finished)
    }
    _Stop();
    _started = true;
    _sceneVersion = version;
    _settingsVersion = settings;
    _cameraKey = key;
    _buffers = buffers;
    _converged.store(false);
    for (auto &b : _buffers) b.second->SetConverged(false);
    nimbus_hydra::SceneDesc scene = _store->Snapshot();
    scene.camera = camera;
    scene.has_camera = cam != nullptr;
    scene.width = w;
    scene.height = h;
    scene.settings = HdNimbusSettings(*_settings);
    for (auto const &b : _buffers) scene.aovs.push_back(b.first.GetString());
    try {
        for (rust::String const &warning : _renderer->reset(scene)) {
            TF_WARN("hdNimbus: %s", std::string(warning).c_str());
        }
    } catch (std::exception const &e) {
        // The renderer is empty now: the thread writes black buffers and ends.
        TF_RUNTIME_ERROR("hdNimbus: %s", e.what());
    }
    _thread = std::thread([this] { _Run(); });
}

void HdNimbusRenderPass::_Run() {
    bool converged = false;
    while (!converged && !_stop.load()) {
        nimbus_hydra::PassInfo info;
        try {
            info = _renderer->render_pass();
        } catch (std::exception const &e) {
            // TfDiagnosticMgr posts errors from other threads to the host.
            TF_RUNTIME_ERROR("hdNimbus: %s", e.what());
            info.converged = true;
        }
        converged = info.converged;
        _progress->Set(info);
        _WriteBuffers();
    }
    if (converged) {
        for (auto &b : _buffers) b.second->SetConverged(true);
        std::fprintf(stderr, "%s\n", std::string(_renderer->stats_line()).c_str());
        std::fflush(stderr);
        _converged.store(true);
    }
}

void HdNimbusRenderPass::_WriteBuffers() {
    std::vector<float> values;
    for (auto &b : _buffers) {
        HdNimbusRenderBuffer *rb = b.second;
        unsigned w = rb->GetWidth(), h = rb->GetHeight();
        size_t k = HdGetComponentCount(rb->GetFormat());
        values.assign(size_t(w) * h * k, 0.0f);
        std::string name = b.first.GetString();
        if (w && h && _renderer->read_aov(name, k, rust::Slice<float>(values.data(), values.size()))) {
            rb->Write(values, k);
        } else {
            // An AOV Nimbus does not have (ids, normals): cleared, -1 for ids.
            rb->Clear(HdGetComponentFormat(rb->GetFormat()) == HdFormatInt32 ? -1.0f : 0.0f);
        }
    }
}

PXR_NAMESPACE_CLOSE_SCOPE
