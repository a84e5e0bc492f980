#include "convert.h"

#include "pxr/base/gf/half.h"
#include "pxr/base/gf/vec2d.h"
#include "pxr/base/gf/vec2f.h"
#include "pxr/base/gf/vec3d.h"
#include "pxr/base/gf/vec3f.h"
#include "pxr/base/gf/vec3h.h"
#include "pxr/base/gf/vec4d.h"
#include "pxr/base/gf/vec4f.h"
#include "pxr/base/tf/token.h"
#include "pxr/usd/sdf/assetPath.h"

PXR_NAMESPACE_OPEN_SCOPE

template <class V>
static bool _Vec(VtValue const &v, std::vector<double> &out) {
    if (!v.IsHolding<V>()) return false;
    V const &x = v.UncheckedGet<V>();
    for (size_t i = 0; i < V::dimension; ++i) out.push_back(double(x[i]));
    return true;
}

template <class T>
static bool _Scalar(VtValue const &v, std::vector<double> &out) {
    if (!v.IsHolding<T>()) return false;
    out.push_back(double(v.UncheckedGet<T>()));
    return true;
}

std::vector<double> HdNimbusNumbers(VtValue const &v) {
    std::vector<double> out;
    _Scalar<float>(v, out) || _Scalar<double>(v, out) || _Scalar<int>(v, out) ||
        _Scalar<long>(v, out) || _Scalar<long long>(v, out) ||
        _Scalar<unsigned int>(v, out) || _Scalar<bool>(v, out) ||
        _Scalar<GfHalf>(v, out) || _Vec<GfVec3f>(v, out) || _Vec<GfVec3d>(v, out) ||
        _Vec<GfVec3h>(v, out) || _Vec<GfVec2f>(v, out) || _Vec<GfVec2d>(v, out) ||
        _Vec<GfVec4f>(v, out) || _Vec<GfVec4d>(v, out);
    return out;
}

double HdNimbusNumber(VtValue const &v, double fallback) {
    std::vector<double> n = HdNimbusNumbers(v);
    return n.empty() ? fallback : n[0];
}

bool HdNimbusBool(VtValue const &v, bool fallback) {
    std::vector<double> n = HdNimbusNumbers(v);
    return n.empty() ? fallback : n[0] != 0.0;
}

std::string HdNimbusText(VtValue const &v) {
    if (v.IsHolding<std::string>()) return v.UncheckedGet<std::string>();
    if (v.IsHolding<TfToken>()) return v.UncheckedGet<TfToken>().GetString();
    if (v.IsHolding<SdfAssetPath>()) {
        SdfAssetPath const &a = v.UncheckedGet<SdfAssetPath>();
        return a.GetResolvedPath().empty() ? a.GetAssetPath() : a.GetResolvedPath();
    }
    return std::string();
}

std::array<double, 16> HdNimbusMatrix(GfMatrix4d const &m) {
    std::array<double, 16> out;
    double const *d = m.data();
    for (int i = 0; i < 16; ++i) out[i] = d[i];
    return out;
}

nimbus_hydra::ParamDesc HdNimbusParam(std::string const &name, VtValue const &v) {
    nimbus_hydra::ParamDesc p;
    p.name = name;
    for (double x : HdNimbusNumbers(v)) p.numbers.push_back(x);
    p.text = HdNimbusText(v);
    return p;
}

void HdNimbusSceneStore::SetLight(SdfPath const &id, nimbus_hydra::LightDesc desc) {
    std::lock_guard<std::mutex> lock(_mutex);
    _unsupportedLights.erase(id);
    _lights[id] = std::move(desc);
    ++_version;
    _Synced();
}

void HdNimbusSceneStore::SetUnsupportedLight(SdfPath const &id, std::string const &type) {
    std::lock_guard<std::mutex> lock(_mutex);
    _lights.erase(id);
    _unsupportedLights[id] = type;
    ++_version;
    _Synced();
}

void HdNimbusSceneStore::SetVolume(SdfPath const &id, HdNimbusVolumeRecord rec) {
    std::lock_guard<std::mutex> lock(_mutex);
    _volumes[id] = std::move(rec);
    ++_version;
    _Synced();
}

void HdNimbusSceneStore::SetMesh(SdfPath const &id, HdNimbusMeshRecord rec) {
    std::lock_guard<std::mutex> lock(_mutex);
    _meshes[id] = std::move(rec);
    ++_version;
    _Synced();
}

void HdNimbusSceneStore::SetField(SdfPath const &id, nimbus_hydra::FieldDesc desc) {
    std::lock_guard<std::mutex> lock(_mutex);
    _fields[id] = std::move(desc);
    ++_version;
    _Synced();
}

void HdNimbusSceneStore::SetRenderSettings(SdfPath const &id, bool active, bool hasShutter,
                                           std::array<double, 2> shutter) {
    std::lock_guard<std::mutex> lock(_mutex);
    auto it = _settingsShutters.find(id);
    if (!hasShutter) {
        if (it == _settingsShutters.end()) return;
        _settingsShutters.erase(it);
    } else {
        auto value = std::make_pair(active, shutter);
        if (it != _settingsShutters.end() && it->second == value) return;
        _settingsShutters[id] = value;
    }
    ++_version;
}

void HdNimbusSceneStore::SetMaterial(SdfPath const &id, HdNimbusMaterialRecord rec) {
    std::lock_guard<std::mutex> lock(_mutex);
    _materials[id] = std::move(rec);
    ++_version;
    _Synced();
}

void HdNimbusSceneStore::Remove(SdfPath const &id) {
    std::lock_guard<std::mutex> lock(_mutex);
    size_t n = _lights.erase(id) + _unsupportedLights.erase(id) + _volumes.erase(id) +
               _meshes.erase(id) + _fields.erase(id) + _materials.erase(id) +
               _settingsShutters.erase(id);
    if (n) ++_version;
}

template <class Desc>
void HdNimbusSceneStore::_FillMaterial(SdfPath const &materialId, Desc &desc) const {
    if (!materialId.IsEmpty()) desc.material_path = materialId.GetString();
    auto m = _materials.find(materialId);
    if (m == _materials.end()) return;
    desc.shader_path = m->second.shaderPath;
    desc.shader_id = m->second.shaderId;
    for (auto const &p : m->second.params) desc.shader_params.push_back(p);
    for (auto const &n : m->second.network) desc.shader_network.push_back(n);
}

nimbus_hydra::SceneDesc HdNimbusSceneStore::Snapshot() const {
    std::lock_guard<std::mutex> lock(_mutex);
    nimbus_hydra::SceneDesc s;
    s.sync_threads = uint32_t(_threads.size());
    for (auto const &l : _lights) s.lights.push_back(l.second);
    for (auto const &u : _unsupportedLights) {
        s.unsupported_lights.push_back(rust::String(u.first.GetString() + " (" + u.second + ")"));
    }
    for (auto const &m : _meshes) {
        nimbus_hydra::MeshDesc desc = m.second.desc;
        _FillMaterial(m.second.materialId, desc);
        s.meshes.push_back(std::move(desc));
    }
    for (auto const &v : _volumes) {
        nimbus_hydra::VolumeDesc desc = v.second.desc;
        for (size_t i = 0; i < desc.fields.size() && i < v.second.fieldIds.size(); ++i) {
            nimbus_hydra::FieldDesc &f = desc.fields[i];
            auto it = _fields.find(v.second.fieldIds[i]);
            if (it == _fields.end()) continue;  // never synced: Rust names it
            f.file = it->second.file;
            f.grid = it->second.grid;
            f.index = it->second.index;
        }
        _FillMaterial(v.second.materialId, desc);
        s.volumes.push_back(std::move(desc));
    }
    // The first active render settings prim (in path order) with a shutter interval.
    for (auto const &r : _settingsShutters) {
        if (!r.second.first) continue;
        s.has_settings_shutter = true;
        s.settings_shutter = r.second.second;
        break;
    }
    return s;
}

rust::Vec<nimbus_hydra::SettingDesc> HdNimbusSettings(HdRenderSettingsMap const &settings) {
    rust::Vec<nimbus_hydra::SettingDesc> out;
    for (auto const &kv : settings) {
        std::string const &key = kv.first.GetString();
        if (key.rfind("nimbus:", 0) != 0) continue;
        nimbus_hydra::SettingDesc s;
        s.key = key;
        std::vector<double> n = HdNimbusNumbers(kv.second);
        if (!n.empty()) {
            s.is_text = false;
            s.number = n[0];
        } else {
            s.is_text = true;
            s.text = HdNimbusText(kv.second);
        }
        out.push_back(std::move(s));
    }
    return out;
}

PXR_NAMESPACE_CLOSE_SCOPE
