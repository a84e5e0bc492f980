#include "nimbus/cpp/exr_deep.h"
#include "nimbus/cpp/guarded.h"
#include "nimbus/src/output/deep_bridge.rs.h"

#include <ImfChannelList.h>
#include <ImfDeepFrameBuffer.h>
#include <ImfDeepScanLineInputFile.h>
#include <ImfDeepScanLineOutputFile.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfPartType.h>
#include <ImfStringAttribute.h>
#include <Iex.h>

#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace nimbus_exr {
namespace {

// Floats per sample in DeepBuffers::samples, in this channel order.
constexpr int kChannels = 6;
const char* const kNames[kChannels] = {"Z", "ZBack", "R", "G", "B", "A"};

// A corrupt header can claim any size; refuse before allocating rather than let the
// allocation (or the machine) fail. 2^28 pixels is a 16k × 16k image; 2^27 samples
// are 3 GiB of floats.
constexpr int64_t kMaxPixels = int64_t(1) << 28;
constexpr uint64_t kMaxSamples = uint64_t(1) << 27;

// Iex's exceptions derive from std::exception: guarded() turns them into capped errors.
template <typename F>
auto guarded(F&& body) -> decltype(body()) {
    return nimbus_cpp::guarded("OpenEXR", std::forward<F>(body));
}

// OpenEXR writes through an OStream; this one fills memory, so Rust can write the bytes
// with its temporary-file-and-rename. OpenEXR seeks back to fill in the offset table.
class MemoryOStream : public Imf::OStream {
public:
    explicit MemoryOStream(const char* name) : Imf::OStream(name) {}
    void write(const char c[], int n) override {
        if (n < 0) throw Iex::ArgExc("negative write size");
        const size_t end = pos_ + size_t(n);
        if (end > bytes.size()) bytes.resize(end);
        std::memcpy(bytes.data() + pos_, c, size_t(n));
        pos_ = end;
    }
    uint64_t tellp() override { return pos_; }
    void seekp(uint64_t pos) override { pos_ = size_t(pos); }
    std::vector<char> bytes;

private:
    size_t pos_ = 0;
};

// Reads from the Rust-owned bytes of a file; a read past their end throws, so a
// truncated file is an error, never an out-of-bounds read.
class MemoryIStream : public Imf::IStream {
public:
    MemoryIStream(const char* name, rust::Slice<const uint8_t> bytes)
        : Imf::IStream(name), bytes_(bytes) {}
    bool read(char c[], int n) override {
        if (n < 0 || pos_ > bytes_.size() || bytes_.size() - pos_ < size_t(n)) {
            throw Iex::InputExc("unexpected end of file");
        }
        std::memcpy(c, bytes_.data() + pos_, size_t(n));
        pos_ += size_t(n);
        return pos_ < bytes_.size();
    }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override { pos_ = size_t(pos); }

private:
    rust::Slice<const uint8_t> bytes_;
    size_t pos_ = 0;
};

Imath::Box2i box(const std::array<int32_t, 4>& b) {
    return Imath::Box2i(Imath::V2i(b[0], b[1]), Imath::V2i(b[2], b[3]));
}

// OpenEXR addresses a slice as base + x * xStride + y * yStride with absolute pixel
// coordinates; shift `origin` (the data window's first pixel) accordingly. Done on
// integers: the shifted pointer may lie outside the buffer and is never dereferenced.
char* shifted(const void* origin, const Imath::Box2i& dw, size_t x_stride, size_t y_stride) {
    const intptr_t offset = intptr_t(dw.min.x) * intptr_t(x_stride) + intptr_t(dw.min.y) * intptr_t(y_stride);
    return reinterpret_cast<char*>(reinterpret_cast<intptr_t>(origin) - offset);
}

// The frame buffer over `counts` (one per pixel of `dw`) and, per channel, a table of
// one pointer per pixel to that pixel's first sample in the interleaved samples. The
// frame buffer refers to the tables, so a reader can set it, read the counts, and only
// then allocate the samples and fill in the tables (`point_at`), as OpenEXR expects.
struct Layout {
    std::vector<std::vector<char*>> pointers;
    Imf::DeepFrameBuffer frame;

    Layout(const Imath::Box2i& dw, const uint32_t* counts) : pointers(kChannels) {
        const size_t width = size_t(dw.max.x - dw.min.x + 1);
        const size_t pixels = width * size_t(dw.max.y - dw.min.y + 1);
        frame.insertSampleCountSlice(Imf::Slice(Imf::UINT, shifted(counts, dw, sizeof(uint32_t), sizeof(uint32_t) * width),
                                                sizeof(uint32_t), sizeof(uint32_t) * width));
        for (int c = 0; c < kChannels; ++c) {
            std::vector<char*>& table = pointers[c];
            table.assign(pixels, nullptr);
            frame.insert(kNames[c], Imf::DeepSlice(Imf::FLOAT, shifted(table.data(), dw, sizeof(char*), sizeof(char*) * width),
                                                   sizeof(char*), sizeof(char*) * width, sizeof(float) * kChannels));
        }
    }

    // Points the tables at `samples`, laid out by `counts` (nullptr for pixels without
    // samples; OpenEXR does not follow those).
    void point_at(const uint32_t* counts, float* samples) {
        for (int c = 0; c < kChannels; ++c) {
            size_t first = 0;
            for (size_t p = 0; p < pointers[c].size(); ++p) {
                pointers[c][p] = counts[p] ? reinterpret_cast<char*>(samples + first * kChannels + c) : nullptr;
                first += counts[p];
            }
        }
    }
};

uint64_t total_samples(const uint32_t* counts, size_t pixels) {
    uint64_t total = 0;
    for (size_t p = 0; p < pixels; ++p) total += counts[p];
    return total;
}

} // namespace

rust::Vec<uint8_t> encode_deep_scanline(rust::Str name, const DeepBuffers& image) {
    return guarded([&] {
        const std::string file(name);
        const Imath::Box2i dw = box(image.data_window);
        const int64_t width = int64_t(dw.max.x) - dw.min.x + 1;
        const int64_t height = int64_t(dw.max.y) - dw.min.y + 1;
        if (width <= 0 || height <= 0 || uint64_t(width * height) != image.counts.size() ||
            total_samples(image.counts.data(), image.counts.size()) * kChannels != image.samples.size()) {
            throw std::runtime_error("inconsistent deep buffers");
        }
        Imf::Header header(box(image.display_window), dw, 1.f, Imath::V2f(0, 0), 1.f, Imf::INCREASING_Y,
                           Imf::ZIPS_COMPRESSION);
        header.setType(Imf::DEEPSCANLINE);
        for (const char* c : kNames) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
        for (const DeepAttribute& a : image.attributes) {
            const std::string key(a.name);
            if (header.find(key) != header.end()) {
                throw std::runtime_error("attribute " + key + " is already in the header");
            }
            header.insert(key, Imf::StringAttribute(std::string(a.value)));
        }
        MemoryOStream out(file.c_str());
        {
            // OpenEXR only reads through these pointers when writing.
            Layout layout(dw, image.counts.data());
            layout.point_at(image.counts.data(), const_cast<float*>(image.samples.data()));
            Imf::DeepScanLineOutputFile output(out, header);
            output.setFrameBuffer(layout.frame);
            output.writePixels(int(height));
        } // the destructor writes the line offset table
        rust::Vec<uint8_t> bytes;
        bytes.reserve(out.bytes.size());
        for (char b : out.bytes) bytes.push_back(uint8_t(b));
        return bytes;
    });
}

DeepBuffers decode_deep_scanline(rust::Str name, rust::Slice<const uint8_t> bytes) {
    return guarded([&] {
        const std::string file(name);
        MemoryIStream in(file.c_str(), bytes);
        Imf::DeepScanLineInputFile input(in);
        const Imf::Header& header = input.header();
        const Imath::Box2i dw = header.dataWindow();
        const Imath::Box2i display = header.displayWindow();
        const int64_t width = int64_t(dw.max.x) - dw.min.x + 1;
        const int64_t height = int64_t(dw.max.y) - dw.min.y + 1;
        if (width <= 0 || height <= 0 || width > kMaxPixels / height) {
            throw std::runtime_error("data window of " + std::to_string(width) + " x " + std::to_string(height) +
                                     " pixels is empty or too large");
        }
        if (!header.channels().findChannel("Z")) throw std::runtime_error("no Z channel");

        DeepBuffers out;
        out.display_window = {display.min.x, display.min.y, display.max.x, display.max.y};
        out.data_window = {dw.min.x, dw.min.y, dw.max.x, dw.max.y};
        out.has_z_back = header.channels().findChannel("ZBack") != nullptr;
        const size_t pixels = size_t(width * height);
        out.counts.reserve(pixels);
        for (size_t p = 0; p < pixels; ++p) out.counts.push_back(0);

        Layout layout(dw, out.counts.data());
        input.setFrameBuffer(layout.frame);
        input.readPixelSampleCounts(dw.min.y, dw.max.y);
        const uint64_t total = total_samples(out.counts.data(), pixels);
        if (total > kMaxSamples) {
            throw std::runtime_error(std::to_string(total) + " deep samples is more than this reader accepts");
        }
        out.samples.reserve(size_t(total) * kChannels);
        for (uint64_t i = 0; i < total * kChannels; ++i) out.samples.push_back(0.f);

        layout.point_at(out.counts.data(), out.samples.data());
        input.readPixels(dw.min.y, dw.max.y);

        for (auto it = header.begin(); it != header.end(); ++it) {
            const std::string key = it.name();
            const auto* text = dynamic_cast<const Imf::StringAttribute*>(&it.attribute());
            // `type` and `name` are OpenEXR's own, not the image's attributes.
            if (!text || key == "type" || key == "name") continue;
            DeepAttribute a;
            a.name = key;
            a.value = text->value();
            out.attributes.push_back(std::move(a));
        }
        return out;
    });
}

} // namespace nimbus_exr
