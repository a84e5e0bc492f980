// nimbus-hydra: a command-line Hydra host. Opens a USD stage, renders it through a
// Hydra render delegate (hdNimbus unless --delegate names another) without GL, and
// writes the color AOV as an EXR (and each `--aov NAME=FILE` as one more): what `husk`
// and `usdrecord` do.
//
// A substitution: the SDK this is built against here has no UsdImaging headers, so the
// host has its own minimal scene delegate over pxr/usd (StageSceneDelegate below)
// instead of UsdImagingDelegate / the stage scene index. It hands over what hdNimbus
// reads: volumes with their openvdbAsset fields (NimbusVolumeAPI's `nimbus:*`
// attributes, `nimbus:fill` too, as constant primvars), meshes and cubes (as meshes,
// as UsdImaging hands them; `nimbus:holdout = false` leaves one out; their `nimbus:*`
// attributes as constant primvars too, which make one a fog box), the UsdLux lights, the camera, and the
// render settings prim's `nimbus:*` attributes as render settings. Light linking as
// UsdImaging hands it over: a light's `lightLink` / `shadowLink` collection that leaves
// out some rprim is named by its collection path (the `lightLink` / `shadowLink` light
// params), and the rprims it includes list that name among their categories.
// Materials: an rprim's bound material (all-purpose binding) and the material's volume
// network (the shader its ri, mtlx, kma or universal volume output leads to, and those
// upstream). Motion: with `--frame`, everything is read at that time code and
// SampleTransform samples each transform over the render camera's shutter as
// UsdImaging does (its ends and the authored samples between); the camera's
// shutter:open / shutter:close are its shutterOpen / shutterClose params. No instancing
// or purposes.
//
//   nimbus-hydra STAGE -o OUT.exr [--res WxH] [--spp N] [--frame F] [--camera PATH]
//                [--delegate NAME] [--aov NAME=FILE.exr]...

#include "pxr/pxr.h"
#include "pxr/base/arch/systemInfo.h"
#include "pxr/base/gf/camera.h"
#include "pxr/base/gf/interval.h"
#include "pxr/base/gf/range1f.h"
#include "pxr/base/plug/registry.h"
#include "pxr/base/tf/diagnostic.h"
#include "pxr/base/tf/getenv.h"
#include "pxr/imaging/cameraUtil/framing.h"
#include "pxr/imaging/hd/camera.h"
#include "pxr/imaging/hd/engine.h"
#include "pxr/imaging/hd/light.h"
#include "pxr/imaging/hd/material.h"
#include "pxr/imaging/hd/renderBuffer.h"
#include "pxr/imaging/hd/renderDelegate.h"
#include "pxr/imaging/hd/renderIndex.h"
#include "pxr/imaging/hd/pluginRenderDelegateUniqueHandle.h"
#include "pxr/imaging/hd/rendererPlugin.h"
#include "pxr/imaging/hd/rendererPluginRegistry.h"
#include "pxr/imaging/hd/sceneDelegate.h"
#include "pxr/imaging/hd/tokens.h"
#include "pxr/imaging/hdx/taskController.h"
#include "pxr/imaging/hio/image.h"
#include "pxr/usd/usd/collectionAPI.h"
#include "pxr/usd/usd/collectionMembershipQuery.h"
#include "pxr/usd/usd/prim.h"
#include "pxr/usd/usd/primRange.h"
#include "pxr/usd/usd/stage.h"
#include "pxr/usd/usdGeom/camera.h"
#include "pxr/usd/usdGeom/cube.h"
#include "pxr/usd/usdGeom/imageable.h"
#include "pxr/usd/usdGeom/mesh.h"
#include "pxr/usd/usdGeom/xformCache.h"
#include "pxr/usd/usdGeom/xformable.h"
#include "pxr/usd/usdLux/boundableLightBase.h"
#include "pxr/usd/usdLux/nonboundableLightBase.h"
#include "pxr/usd/usdRender/settings.h"
#include "pxr/usd/usdShade/material.h"
#include "pxr/usd/usdShade/materialBindingAPI.h"
#include "pxr/usd/usdShade/shader.h"
#include "pxr/usd/usdVol/openVDBAsset.h"
#include "pxr/usd/usdVol/volume.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <utility>
#include <vector>

PXR_NAMESPACE_USING_DIRECTIVE

namespace {

// The stage as Hydra prims: the subset hdNimbus reads (see the file comment).
class StageSceneDelegate final : public HdSceneDelegate {
public:
    // Everything is read at `time` (the frame; UsdTimeCode::Default() without one).
    StageSceneDelegate(HdRenderIndex *index, UsdStageRefPtr stage, UsdTimeCode time)
        : HdSceneDelegate(index, SdfPath::AbsoluteRootPath()), _stage(stage), _time(time),
          _xf(time) {}

    // The camera whose shutter the transforms are sampled over (as
    // UsdImagingDelegate::SetCameraForSampling).
    void SetCameraForSampling(SdfPath const &camera) { _samplingCamera = camera; }

    // Inserts the stage's prims into the render index.
    void Populate() {
        HdRenderIndex &index = GetRenderIndex();
        for (UsdPrim const &prim : _stage->Traverse()) {
            SdfPath const &p = prim.GetPath();
            if (prim.IsA<UsdVolVolume>()) {
                index.InsertRprim(HdPrimTypeTokens->volume, this, p);
                _rprims.push_back(p);
                for (auto const &f : UsdVolVolume(prim).GetFieldPaths()) {
                    UsdPrim field = _stage->GetPrimAtPath(f.second);
                    TfToken type = field && field.IsA<UsdVolOpenVDBAsset>()
                                       ? TfToken("openvdbAsset")
                                       : TfToken("field3dAsset");
                    if (!index.GetBprim(type, f.second)) index.InsertBprim(type, this, f.second);
                }
            } else if (prim.IsA<UsdGeomMesh>() || prim.IsA<UsdGeomCube>()) {
                // `nimbus:holdout = false` leaves a gprim out, as the USD reader does.
                bool holdout = true;
                UsdAttribute h = prim.GetAttribute(TfToken("nimbus:holdout"));
                if (h) h.Get(&holdout, _time);
                // A Cube as UsdImaging hands it over: a mesh of its six faces.
                if (holdout) {
                    index.InsertRprim(HdPrimTypeTokens->mesh, this, p);
                    _rprims.push_back(p);
                }
            } else if (prim.IsA<UsdShadeMaterial>()) {
                index.InsertSprim(HdPrimTypeTokens->material, this, p);
            } else if (prim.IsA<UsdGeomCamera>()) {
                index.InsertSprim(HdPrimTypeTokens->camera, this, p);
                if (_firstCamera.IsEmpty()) _firstCamera = p;
            } else if (prim.IsA<UsdLuxBoundableLightBase>() ||
                       prim.IsA<UsdLuxNonboundableLightBase>()) {
                // The schema's type name, lower camel case, is Hydra's light type.
                std::string t = prim.GetTypeName().GetString();
                if (!t.empty()) t[0] = char(std::tolower(t[0]));
                TfToken type(t);
                if (HdPrimTypeIsLight(type) && index.IsSprimTypeSupported(type)) {
                    index.InsertSprim(type, this, p);
                    _lights.push_back(prim);
                } else {
                    TF_WARN("nimbus-hydra: light %s: type %s is not a Hydra light type the delegate supports; left out",
                            p.GetText(), t.c_str());
                }
            }
        }
    }

    // Each light's linking collections: named when they leave out some rprim (a
    // collection of every rprim is Hydra's empty name, as UsdImaging's collection
    // cache makes it), the name added to the categories of the rprims it includes.
    void ComputeLinking() {
        for (UsdPrim const &light : _lights) {
            for (TfToken const &name : {HdTokens->lightLink, HdTokens->shadowLink}) {
                UsdCollectionAPI collection(light, name);
                UsdCollectionMembershipQuery query = collection.ComputeMembershipQuery();
                std::vector<SdfPath> members;
                for (SdfPath const &r : _rprims) {
                    if (query.IsPathIncluded(r)) members.push_back(r);
                }
                if (members.size() == _rprims.size()) continue;
                TfToken id(collection.GetCollectionPath().GetString());
                _links[{light.GetPath(), name}] = id;
                for (SdfPath const &r : members) _categories[r].push_back(id);
            }
        }
    }

    SdfPath FirstCamera() const { return _firstCamera; }

    VtArray<TfToken> GetCategories(SdfPath const &id) override {
        auto it = _categories.find(id);
        return it == _categories.end() ? VtArray<TfToken>() : it->second;
    }

    GfMatrix4d GetTransform(SdfPath const &id) override {
        UsdPrim prim = _stage->GetPrimAtPath(id);
        return prim ? _xf.GetLocalToWorldTransform(prim) : GfMatrix4d(1.0);
    }

    // The transform at the sample times (_SampleTimes), each evaluated at the frame
    // plus that time; the times handed over as floats (Hydra's), from the frame.
    size_t SampleTransform(SdfPath const &id, size_t maxSampleCount, float *sampleTimes,
                           GfMatrix4d *sampleValues) override {
        UsdPrim prim = _stage->GetPrimAtPath(id);
        std::vector<double> times = _SampleTimes(prim);
        for (size_t i = 0; i < times.size() && i < maxSampleCount; ++i) {
            sampleTimes[i] = float(times[i]);
            if (times[i] == 0.0 || !prim) {
                sampleValues[i] = GetTransform(id);
            } else {
                UsdGeomXformCache at(UsdTimeCode(_time.GetValue() + times[i]));
                sampleValues[i] = at.GetLocalToWorldTransform(prim);
            }
        }
        return times.size();
    }

    bool GetVisible(SdfPath const &id) override {
        UsdGeomImageable im(_stage->GetPrimAtPath(id));
        return !im || im.ComputeVisibility(_time) != UsdGeomTokens->invisible;
    }

    bool GetDoubleSided(SdfPath const &id) override {
        bool d = false;
        UsdGeomMesh(_stage->GetPrimAtPath(id)).GetDoubleSidedAttr().Get(&d, _time);
        return d;
    }

    HdMeshTopology GetMeshTopology(SdfPath const &id) override {
        UsdPrim prim = _stage->GetPrimAtPath(id);
        if (prim.IsA<UsdGeomCube>()) {
            // Corners by bits (1: +x, 2: +y, 4: +z), faces as the USD reader's.
            VtIntArray counts(6, 4);
            VtIntArray indices = {0, 2, 6, 4, 1, 5, 7, 3, 0, 4, 5, 1,
                                  2, 3, 7, 6, 0, 1, 3, 2, 4, 6, 7, 5};
            return HdMeshTopology(PxOsdOpenSubdivTokens->none, HdTokens->rightHanded, counts,
                                  indices);
        }
        UsdGeomMesh mesh(prim);
        VtIntArray counts, indices, holes;
        mesh.GetFaceVertexCountsAttr().Get(&counts, _time);
        mesh.GetFaceVertexIndicesAttr().Get(&indices, _time);
        mesh.GetHoleIndicesAttr().Get(&holes, _time);
        HdMeshTopology t(PxOsdOpenSubdivTokens->none, HdTokens->rightHanded, counts, indices);
        t.SetHoleIndices(holes);
        return t;
    }

    VtValue Get(SdfPath const &id, TfToken const &key) override {
        UsdPrim prim = _stage->GetPrimAtPath(id);
        if (!prim) return VtValue();
        if (key == HdTokens->points && prim.IsA<UsdGeomCube>()) {
            double size = 2.0;
            UsdGeomCube(prim).GetSizeAttr().Get(&size, _time);
            float h = float(size / 2.0);
            VtVec3fArray points(8);
            for (int i = 0; i < 8; ++i) {
                points[i] = GfVec3f(i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h);
            }
            return VtValue(points);
        }
        if (key == HdTokens->points) {
            VtVec3fArray points;
            UsdGeomMesh(prim).GetPointsAttr().Get(&points, _time);
            return VtValue(points);
        }
        UsdAttribute a = prim.GetAttribute(key);
        VtValue v;
        if (a) a.Get(&v, _time);
        return v;
    }

    // The material bound to an rprim (its all-purpose binding, inherited).
    SdfPath GetMaterialId(SdfPath const &id) override {
        UsdPrim prim = _stage->GetPrimAtPath(id);
        if (!prim) return SdfPath();
        UsdShadeMaterial m = UsdShadeMaterialBindingAPI(prim).ComputeBoundMaterial();
        return m ? m.GetPath() : SdfPath();
    }

    // A material's volume network as UsdImaging hands it over: the shader its
    // `outputs:ri:volume`, `outputs:mtlx:volume`, `outputs:kma:volume` or
    // `outputs:volume` leads to (through node graphs), and the shaders upstream of it,
    // upstream first; parameters by input name, interface inputs resolved.
    VtValue GetMaterialResource(SdfPath const &id) override {
        HdMaterialNetworkMap map;
        UsdShadeMaterial material(_stage->GetPrimAtPath(id));
        if (!material) return VtValue(map);
        UsdShadeShader source =
            material.ComputeVolumeSource({TfToken("ri"), TfToken("mtlx"), TfToken("kma")});
        if (!source) return VtValue(map);
        std::set<SdfPath> seen;
        _AddNode(source, map.map[HdMaterialTerminalTokens->volume], seen, _time);
        map.terminals.push_back(source.GetPath());
        return VtValue(map);
    }

    HdVolumeFieldDescriptorVector GetVolumeFieldDescriptors(SdfPath const &id) override {
        HdVolumeFieldDescriptorVector out;
        for (auto const &f : UsdVolVolume(_stage->GetPrimAtPath(id)).GetFieldPaths()) {
            UsdPrim field = _stage->GetPrimAtPath(f.second);
            TfToken type = field && field.IsA<UsdVolOpenVDBAsset>() ? TfToken("openvdbAsset")
                                                                    : TfToken("field3dAsset");
            out.emplace_back(f.first, type, f.second);
        }
        return out;
    }

    // A volume's or a gprim's NimbusVolumeAPI attributes (`nimbus:*`) as constant
    // primvars.
    HdPrimvarDescriptorVector GetPrimvarDescriptors(SdfPath const &id,
                                                    HdInterpolation interpolation) override {
        HdPrimvarDescriptorVector out;
        UsdPrim prim = _stage->GetPrimAtPath(id);
        if (interpolation != HdInterpolationConstant || !prim) return out;
        for (UsdAttribute const &a : prim.GetAttributes()) {
            if (a.GetName().GetString().rfind("nimbus:", 0) == 0 && a.HasAuthoredValue()) {
                out.emplace_back(a.GetName(), HdInterpolationConstant);
            }
        }
        return out;
    }

    VtValue GetLightParamValue(SdfPath const &id, TfToken const &name) override {
        if (name == HdTokens->lightLink || name == HdTokens->shadowLink) {
            auto it = _links.find({id, name});
            return VtValue(it == _links.end() ? TfToken() : it->second);
        }
        UsdPrim prim = _stage->GetPrimAtPath(id);
        if (!prim) return VtValue();
        VtValue v;
        for (std::string const &n : {"inputs:" + name.GetString(), name.GetString()}) {
            UsdAttribute a = prim.GetAttribute(TfToken(n));
            if (a && a.Get(&v, _time)) {
                if (v.IsHolding<SdfAssetPath>()) {
                    SdfAssetPath const &p = v.UncheckedGet<SdfAssetPath>();
                    return VtValue(SdfAssetPath(p.GetAssetPath(), p.GetResolvedPath()));
                }
                return v;
            }
        }
        return VtValue();
    }

    // UsdGeomCamera in Hydra's units: lengths in scene units (tenths of the schema's).
    VtValue GetCameraParamValue(SdfPath const &id, TfToken const &key) override {
        UsdGeomCamera cam(_stage->GetPrimAtPath(id));
        if (!cam) return VtValue();
        GfCamera c = cam.GetCamera(_time);
        double const unit = GfCamera::APERTURE_UNIT;
        if (key == HdCameraTokens->projection) {
            return VtValue(c.GetProjection() == GfCamera::Orthographic ? HdCamera::Orthographic
                                                                       : HdCamera::Perspective);
        }
        if (key == HdCameraTokens->focalLength) return VtValue(float(c.GetFocalLength() * unit));
        if (key == HdCameraTokens->horizontalAperture)
            return VtValue(float(c.GetHorizontalAperture() * unit));
        if (key == HdCameraTokens->verticalAperture)
            return VtValue(float(c.GetVerticalAperture() * unit));
        if (key == HdCameraTokens->horizontalApertureOffset)
            return VtValue(float(c.GetHorizontalApertureOffset() * unit));
        if (key == HdCameraTokens->verticalApertureOffset)
            return VtValue(float(c.GetVerticalApertureOffset() * unit));
        if (key == HdCameraTokens->clippingRange) {
            GfRange1f r = c.GetClippingRange();
            return VtValue(r);
        }
        if (key == HdCameraTokens->fStop) return VtValue(c.GetFStop());
        if (key == HdCameraTokens->focusDistance) return VtValue(c.GetFocusDistance());
        // The shutter as UsdImaging hands it over: time codes from the frame, doubles.
        if (key == HdCameraTokens->shutterOpen || key == HdCameraTokens->shutterClose) {
            double v = 0.0;
            (key == HdCameraTokens->shutterOpen ? cam.GetShutterOpenAttr()
                                                : cam.GetShutterCloseAttr())
                .Get(&v, _time);
            return VtValue(v);
        }
        return VtValue();
    }

private:
    static void _AddNode(UsdShadeShader const &shader, HdMaterialNetwork &net,
                         std::set<SdfPath> &seen, UsdTimeCode time) {
        if (!seen.insert(shader.GetPath()).second) return;
        HdMaterialNode node;
        node.path = shader.GetPath();
        shader.GetShaderId(&node.identifier);
        for (UsdShadeInput const &input : shader.GetInputs()) {
            UsdShadeAttributeVector attrs = input.GetValueProducingAttributes();
            if (attrs.empty()) continue;
            UsdAttribute const &a = attrs[0];
            if (UsdShadeOutput::IsOutput(a)) {
                UsdShadeShader upstream(a.GetPrim());
                if (!upstream) continue;
                _AddNode(upstream, net, seen, time);
                HdMaterialRelationship r;
                r.inputId = upstream.GetPath();
                r.inputName = UsdShadeOutput(a).GetBaseName();
                r.outputId = shader.GetPath();
                r.outputName = input.GetBaseName();
                net.relationships.push_back(r);
            } else {
                VtValue v;
                if (a.Get(&v, time)) node.parameters[input.GetBaseName()] = v;
            }
        }
        net.nodes.push_back(node);
    }

    // The times (from the frame) to sample `prim`'s transform at, as UsdImaging picks
    // them: with a frame and the sampling camera's shutter open (open < close), the
    // shutter's two ends and every authored time sample of the xformOps of `prim` and
    // its ancestors (as far as the transform inherits) between them; else the frame
    // alone (also when no op might vary).
    std::vector<double> _SampleTimes(UsdPrim const &prim) const {
        std::vector<double> frameOnly = {0.0};
        UsdGeomCamera cam(_stage->GetPrimAtPath(_samplingCamera));
        if (!prim || _time.IsDefault() || !cam) return frameOnly;
        double open = 0.0, close = 0.0;
        cam.GetShutterOpenAttr().Get(&open, _time);
        cam.GetShutterCloseAttr().Get(&close, _time);
        if (!(open < close)) return frameOnly;
        double const frame = _time.GetValue();
        std::vector<double> times = {open, close};
        bool varies = false;
        for (UsdPrim p = prim; p && !p.IsPseudoRoot(); p = p.GetParent()) {
            UsdGeomXformable x(p);
            if (!x) continue;
            varies = varies || x.TransformMightBeTimeVarying();
            std::vector<double> authored;
            x.GetTimeSamplesInInterval(GfInterval(frame + open, frame + close), &authored);
            for (double t : authored) {
                if (t - frame > open && t - frame < close) times.push_back(t - frame);
            }
            if (x.GetResetXformStack()) break;
        }
        if (!varies) return frameOnly;
        std::sort(times.begin(), times.end());
        times.erase(std::unique(times.begin(), times.end()), times.end());
        return times;
    }

    UsdStageRefPtr _stage;
    UsdTimeCode _time;
    UsdGeomXformCache _xf;
    SdfPath _samplingCamera;
    SdfPath _firstCamera;
    // The rprims inserted and the lights, in stage order; the linking (ComputeLinking).
    std::vector<SdfPath> _rprims;
    std::vector<UsdPrim> _lights;
    std::map<std::pair<SdfPath, TfToken>, TfToken> _links;
    std::map<SdfPath, VtArray<TfToken>> _categories;
};

int Usage(char const *why) {
    std::fprintf(stderr,
                 "nimbus-hydra: error: %s\nusage: nimbus-hydra STAGE -o OUT.exr [--res WxH] "
                 "[--spp N] [--frame F] [--camera PATH] [--delegate NAME] [--aov NAME=FILE.exr]...\n",
                 why);
    return 2;
}

// Writes render buffer `rb` (float, 1 to 4 components) to `path` through Hio.
bool WriteBuffer(HdRenderBuffer *rb, std::string const &path) {
    rb->Resolve();
    HioImage::StorageSpec spec;
    spec.width = int(rb->GetWidth());
    spec.height = int(rb->GetHeight());
    switch (rb->GetFormat()) {
    case HdFormatFloat32: spec.format = HioFormatFloat32; break;
    case HdFormatFloat32Vec2: spec.format = HioFormatFloat32Vec2; break;
    case HdFormatFloat32Vec3: spec.format = HioFormatFloat32Vec3; break;
    case HdFormatFloat32Vec4: spec.format = HioFormatFloat32Vec4; break;
    default:
        std::fprintf(stderr, "nimbus-hydra: error: %s: the buffer is not float\n", path.c_str());
        return false;
    }
    spec.flipped = true;  // Hydra's rows start at the bottom
    spec.data = rb->Map();
    HioImageSharedPtr image = HioImage::OpenForWriting(path);
    bool ok = image && image->Write(spec);
    rb->Unmap();
    if (!ok) std::fprintf(stderr, "nimbus-hydra: error: %s: cannot write the image\n", path.c_str());
    return ok;
}

}  // namespace

int main(int argc, char **argv) {
    std::string stagePath, out, cameraArg, delegateName = "HdNimbusRendererPlugin";
    int width = 0, height = 0, spp = 0;
    // --frame F: the time code everything is read at (as `nimbus render --frame`);
    // without it, the default time (and no motion blur: no shutter interval to sample).
    UsdTimeCode time = UsdTimeCode::Default();
    // --aov NAME=FILE: the AOV's name (a light group `lightgroup:key`, `direct`, …, as
    // the delegate names it) and the file to write it to.
    std::vector<std::pair<TfToken, std::string>> aovs;
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : std::string(); };
        if (a == "-o") out = next();
        else if (a == "--res") {
            std::string r = next();
            if (std::sscanf(r.c_str(), "%dx%d", &width, &height) != 2 || width <= 0 || height <= 0)
                return Usage("--res takes WxH");
        } else if (a == "--spp") spp = std::atoi(next().c_str());
        else if (a == "--frame") {
            std::string f = next();
            char *end = nullptr;
            double v = std::strtod(f.c_str(), &end);
            if (f.empty() || *end != '\0' || !std::isfinite(v)) return Usage("--frame takes a number");
            time = UsdTimeCode(v);
        }
        else if (a == "--camera") cameraArg = next();
        else if (a == "--delegate") delegateName = next();
        else if (a == "--aov") {
            std::string v = next();
            size_t eq = v.rfind('=');
            if (eq == std::string::npos || eq == 0 || eq + 1 == v.size())
                return Usage("--aov takes NAME=FILE.exr");
            aovs.emplace_back(TfToken(v.substr(0, eq)), v.substr(eq + 1));
        }
        else if (!a.empty() && a[0] == '-') return Usage(("unknown option " + a).c_str());
        else stagePath = a;
    }
    if (stagePath.empty() || out.empty()) return Usage("a stage and -o OUT.exr are required");

    // hdNimbus lives beside this program (hydra/hdNimbus/plugInfo.json).
    std::string self = ArchGetExecutablePath();
    std::string dir = self.substr(0, self.rfind('/'));
    PlugRegistry::GetInstance().RegisterPlugins(dir + "/hdNimbus");

    UsdStageRefPtr stage = UsdStage::Open(stagePath);
    if (!stage) {
        std::fprintf(stderr, "nimbus-hydra: error: %s: cannot open the stage\n", stagePath.c_str());
        return 1;
    }
    HdRendererPluginRegistry &plugins = HdRendererPluginRegistry::GetInstance();
    HdPluginRenderDelegateUniqueHandle delegate =
        plugins.CreateRenderDelegate(TfToken(delegateName));
    if (!delegate) {
        std::fprintf(stderr, "nimbus-hydra: error: no render delegate %s\n", delegateName.c_str());
        return 1;
    }
    // The render settings prim's nimbus:* attributes and resolution, then the flags.
    UsdRenderSettings settings = UsdRenderSettings::GetStageRenderSettings(stage);
    if (!settings) {
        for (UsdPrim const &p : stage->Traverse()) {
            if (p.IsA<UsdRenderSettings>()) {
                settings = UsdRenderSettings(p);
                break;
            }
        }
    }
    SdfPath cameraPath = cameraArg.empty() ? SdfPath() : SdfPath(cameraArg);
    if (settings) {
        for (UsdAttribute const &a : settings.GetPrim().GetAttributes()) {
            VtValue v;
            if (a.GetName().GetString().rfind("nimbus:", 0) == 0 && a.Get(&v, time)) {
                delegate->SetRenderSetting(a.GetName(), v);
            }
        }
        GfVec2i res;
        if (width == 0 && settings.GetResolutionAttr().Get(&res, time)) {
            width = res[0];
            height = res[1];
        }
        SdfPathVector cams;
        if (cameraPath.IsEmpty() && settings.GetCameraRel().GetForwardedTargets(&cams) &&
            !cams.empty()) {
            cameraPath = cams[0];
        }
    }
    if (width == 0) {
        width = 640;
        height = 480;
    }
    if (spp > 0) delegate->SetRenderSetting(TfToken("nimbus:samples"), VtValue(spp));

    HdRenderIndex *index = HdRenderIndex::New(delegate.Get(), {});
    StageSceneDelegate scene(index, stage, time);
    scene.Populate();
    scene.ComputeLinking();
    if (cameraPath.IsEmpty()) cameraPath = scene.FirstCamera();
    if (cameraPath.IsEmpty()) {
        std::fprintf(stderr, "nimbus-hydra: error: %s: no camera (name one with --camera)\n",
                     stagePath.c_str());
        return 1;
    }
    scene.SetCameraForSampling(cameraPath);
    {
        HdxTaskController tasks(index, SdfPath("/nimbusHydraTasks"), /*gpuEnabled=*/false);
        TfTokenVector outputs = {HdAovTokens->color};
        for (auto const &a : aovs) outputs.push_back(a.first);
        tasks.SetRenderOutputs(outputs);
        tasks.SetRenderBufferSize(GfVec2i(width, height));
        tasks.SetFraming(CameraUtilFraming(GfRect2i(GfVec2i(0, 0), width, height)));
        tasks.SetCameraPath(cameraPath);
        HdEngine engine;
        auto start = std::chrono::steady_clock::now();
        do {
            HdTaskSharedPtrVector t = tasks.GetRenderingTasks();
            engine.Execute(index, &t);
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        } while (!tasks.IsConverged());
        double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        HdRenderBuffer *color = tasks.GetRenderOutput(HdAovTokens->color);
        if (!color) {
            std::fprintf(stderr, "nimbus-hydra: error: no color buffer\n");
            return 1;
        }
        if (!WriteBuffer(color, out)) return 1;
        for (auto const &a : aovs) {
            HdRenderBuffer *rb = tasks.GetRenderOutput(a.first);
            if (!rb) {
                std::fprintf(stderr, "nimbus-hydra: error: no buffer for AOV %s\n",
                             a.first.GetText());
                return 1;
            }
            if (!WriteBuffer(rb, a.second)) return 1;
        }
        std::fprintf(stderr, "nimbus-hydra: wrote %s (%dx%d, %.2f s through %s)\n", out.c_str(),
                     width, height, seconds, delegateName.c_str());
    }
    delete index;
    return 0;
}
