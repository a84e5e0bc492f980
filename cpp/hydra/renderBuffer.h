// hdNimbus' render buffer: host memory of one AOV, written by the render pass after
// each pass.
#ifndef HDNIMBUS_RENDER_BUFFER_H
#define HDNIMBUS_RENDER_BUFFER_H

#include "pxr/pxr.h"
#include "pxr/imaging/hd/renderBuffer.h"

#include <atomic>
#include <mutex>
#include <vector>

PXR_NAMESPACE_OPEN_SCOPE

class HdNimbusRenderBuffer final : public HdRenderBuffer {
public:
    explicit HdNimbusRenderBuffer(SdfPath const &id) : HdRenderBuffer(id) {}
    ~HdNimbusRenderBuffer() override = default;

    bool Allocate(GfVec3i const &dimensions, HdFormat format, bool multiSampled) override;
    unsigned int GetWidth() const override { return _width; }
    unsigned int GetHeight() const override { return _height; }
    unsigned int GetDepth() const override { return 1; }
    HdFormat GetFormat() const override { return _format; }
    bool IsMultiSampled() const override { return false; }
    void *Map() override;
    void Unmap() override;
    bool IsMapped() const override { return _mappers.load() != 0; }
    void Resolve() override {}
    bool IsConverged() const override { return _converged.load(); }

    void SetConverged(bool converged) { _converged.store(converged); }
    // Writes `values` (`components` floats per pixel, bottom row first) converted to
    // the buffer's format; components beyond `components` are 0 (alpha: 1).
    void Write(std::vector<float> const &values, size_t components);
    // Fills every component with `value`.
    void Clear(float value);

private:
    void _Deallocate() override;

    unsigned int _width = 0, _height = 0;
    HdFormat _format = HdFormatInvalid;
    std::vector<uint8_t> _buffer;
    std::atomic<int> _mappers{0};
    std::atomic<bool> _converged{false};
    std::mutex _mutex;
};

PXR_NAMESPACE_CLOSE_SCOPE

#endif
