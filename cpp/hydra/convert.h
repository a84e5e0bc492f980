// hdNimbus: the scene-description store and the conversions from Hydra's values to the
// plain structs handed to Rust (nimbus-hydra/src/ffi.rs). Nothing here renders.
#ifndef HDNIMBUS_CONVERT_H
#define HDNIMBUS_CONVERT_H

#include "pxr/pxr.h"
#include "pxr/base/gf/matrix4d.h"
#include "pxr/base/vt/value.h"
#include "pxr/imaging/hd/renderDelegate.h"
#include "pxr/usd/sdf/path.h"

#include "nimbus-hydra/src/ffi.rs.h"

#include <atomic>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <string>
#include <vector>

PXR_NAMESPACE_OPEN_SCOPE

// Numbers of a VtValue holding a scalar (float, double, int, long, bool, half) or a
// vector (GfVec2/3/4 of f/d/h/i); empty when it holds neither.
std::vector<double> HdNimbusNumbers(VtValue const &v);
// The first number, or `fallback`.
double HdNimbusNumber(VtValue const &v, double fallback);
bool HdNimbusBool(VtValue const &v, bool fallback);
// Text of a string, token or asset path (its resolved path when resolved); "" else.
std::string HdNimbusText(VtValue const &v);
// GfMatrix4d's 16 numbers in its memory order.
std::array<double, 16> HdNimbusMatrix(GfMatrix4d const &m);
// A ParamDesc of `name` and `v` (numbers, or text).
nimbus_hydra::ParamDesc HdNimbusParam(std::string const &name, VtValue const &v);

// A volume as synced: its description, the field bprims it names and its material.
struct HdNimbusVolumeRecord {
    nimbus_hydra::VolumeDesc desc;
    std::vector<SdfPath> fieldIds;
    SdfPath materialId;
};

// A mesh as synced: its description and its material.
struct HdNimbusMeshRecord {
    nimbus_hydra::MeshDesc desc;
    SdfPath materialId;
};

// A material's volume shader, as synced.
struct HdNimbusMaterialRecord {
    std::string shaderPath;
    std::string shaderId;
    std::vector<nimbus_hydra::ParamDesc> params;
    // Every node of the material's networks, with its connected inputs.
    std::vector<nimbus_hydra::ShaderNodeDesc> network;
};

// What the prims' Syncs (on several threads at once) leave for the render pass. Every
// access locks: Syncs write a prim's record once per change, the render pass reads
// all of them once per change; neither is in a render's hot path.
class HdNimbusSceneStore {
public:
    void SetLight(SdfPath const &id, nimbus_hydra::LightDesc desc);
    void SetUnsupportedLight(SdfPath const &id, std::string const &type);
    void SetVolume(SdfPath const &id, HdNimbusVolumeRecord rec);
    void SetMesh(SdfPath const &id, HdNimbusMeshRecord rec);
    void SetField(SdfPath const &id, nimbus_hydra::FieldDesc desc);
    void SetMaterial(SdfPath const &id, HdNimbusMaterialRecord rec);
    // A render settings prim: whether it is active, and its shutter interval (open,
    // close) when it has one.
    void SetRenderSettings(SdfPath const &id, bool active, bool hasShutter,
                           std::array<double, 2> shutter);
    // Forgets the prim `id` of any kind.
    void Remove(SdfPath const &id);
    // Bumped by every change.
    uint64_t Version() const { return _version.load(); }
    // Everything, with the volumes' fields and the volumes' and meshes' materials
    // filled in.
    nimbus_hydra::SceneDesc Snapshot() const;

private:
    // Under the lock: the material `materialId`'s path and volume shader into `desc`
    // (a VolumeDesc or a MeshDesc).
    template <class Desc>
    void _FillMaterial(SdfPath const &materialId, Desc &desc) const;
    // Under the lock: a prim was synced on this thread.
    void _Synced() { _threads.insert(std::this_thread::get_id()); }

    mutable std::mutex _mutex;
    // The threads prims were synced on (reported in the render's statistics).
    std::set<std::thread::id> _threads;
    std::atomic<uint64_t> _version{1};
    std::map<SdfPath, nimbus_hydra::LightDesc> _lights;
    std::map<SdfPath, std::string> _unsupportedLights;
    std::map<SdfPath, HdNimbusVolumeRecord> _volumes;
    std::map<SdfPath, HdNimbusMeshRecord> _meshes;
    std::map<SdfPath, nimbus_hydra::FieldDesc> _fields;
    std::map<SdfPath, HdNimbusMaterialRecord> _materials;
    // The render settings prims with a shutter interval: active, (open, close).
    std::map<SdfPath, std::pair<bool, std::array<double, 2>>> _settingsShutters;
};

// The host's render settings named `nimbus:*` as plain data (the rest are the host's own).
rust::Vec<nimbus_hydra::SettingDesc> HdNimbusSettings(HdRenderSettingsMap const &settings);

PXR_NAMESPACE_CLOSE_SCOPE

#endif
