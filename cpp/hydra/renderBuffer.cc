#include "renderBuffer.h"

#include "pxr/base/gf/half.h"
#include "pxr/base/gf/vec3i.h"
#include "pxr/base/tf/diagnostic.h"

#include <algorithm>
#include <cstring>

PXR_NAMESPACE_OPEN_SCOPE

bool HdNimbusRenderBuffer::Allocate(GfVec3i const &dimensions, HdFormat format,
                                    bool multiSampled) {
    _Deallocate();
    if (dimensions[2] != 1) {
        TF_WARN("hdNimbus: render buffer %s: depth %d is not supported", GetId().GetText(),
                dimensions[2]);
        return false;
    }
    std::lock_guard<std::mutex> lock(_mutex);
    _width = unsigned(std::max(dimensions[0], 0));
    _height = unsigned(std::max(dimensions[1], 0));
    _format = format;
    _buffer.assign(size_t(_width) * _height * HdDataSizeOfFormat(format), 0);
    _converged.store(false);
    return true;
}

void HdNimbusRenderBuffer::_Deallocate() {
    std::lock_guard<std::mutex> lock(_mutex);
    _width = _height = 0;
    _format = HdFormatInvalid;
    _buffer.clear();
    _mappers.store(0);
    _converged.store(false);
}

void *HdNimbusRenderBuffer::Map() {
    _mappers++;
    return _buffer.data();
}

void HdNimbusRenderBuffer::Unmap() { _mappers--; }

void HdNimbusRenderBuffer::Write(std::vector<float> const &values, size_t components) {
    std::lock_guard<std::mutex> lock(_mutex);
    size_t n = size_t(_width) * _height;
    size_t k = HdGetComponentCount(_format);
    HdFormat c = HdGetComponentFormat(_format);
    if (values.size() < n * components) return;
    for (size_t p = 0; p < n; ++p) {
        for (size_t i = 0; i < k; ++i) {
            float v = i < components ? values[p * components + i] : (i == 3 ? 1.0f : 0.0f);
            size_t at = p * k + i;
            switch (c) {
            case HdFormatFloat32:
                reinterpret_cast<float *>(_buffer.data())[at] = v;
                break;
            case HdFormatFloat16:
                reinterpret_cast<GfHalf *>(_buffer.data())[at] = GfHalf(v);
                break;
            case HdFormatUNorm8:
                _buffer[at] = uint8_t(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f);
                break;
            case HdFormatInt32:
                reinterpret_cast<int32_t *>(_buffer.data())[at] = int32_t(v);
                break;
            default:
                break;
            }
        }
    }
}

void HdNimbusRenderBuffer::Clear(float value) {
    size_t n = size_t(_width) * _height;
    Write(std::vector<float>(n * HdGetComponentCount(_format), value),
          HdGetComponentCount(_format));
}

PXR_NAMESPACE_CLOSE_SCOPE
