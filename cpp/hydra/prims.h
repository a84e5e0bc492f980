// hdNimbus' prims: each Sync reads what its scene delegate has for it, converts it to a
// plain description (convert.h) and leaves it in the delegate's store.
#ifndef HDNIMBUS_PRIMS_H
#define HDNIMBUS_PRIMS_H

#include "pxr/pxr.h"
#include "pxr/imaging/hd/camera.h"
#include "pxr/imaging/hd/field.h"
#include "pxr/imaging/hd/light.h"
#include "pxr/imaging/hd/material.h"
#include "pxr/imaging/hd/mesh.h"
#include "pxr/imaging/hd/renderSettings.h"
#include "pxr/imaging/hd/volume.h"

#include "nimbus-hydra/src/ffi.rs.h"

PXR_NAMESPACE_OPEN_SCOPE

// A volume rprim: its openvdbAsset fields, constant primvars (nimbus:* as
// NimbusVolumeAPI names them), transform and material.
class HdNimbusVolume final : public HdVolume {
public:
    explicit HdNimbusVolume(SdfPath const &id) : HdVolume(id) {}
    HdDirtyBits GetInitialDirtyBitsMask() const override;
    void Sync(HdSceneDelegate *delegate, HdRenderParam *param, HdDirtyBits *dirtyBits,
              TfToken const &reprToken) override;
    void Finalize(HdRenderParam *param) override;

protected:
    HdDirtyBits _PropagateDirtyBits(HdDirtyBits bits) const override { return bits; }
    void _InitRepr(TfToken const &reprToken, HdDirtyBits *dirtyBits) override {}
    TfTokenVector const &GetBuiltinPrimvarNames() const override;
};

// A mesh rprim: its control cage, constant primvars, transform and material (a holdout,
// a black matte occluder, or a fog box: the Rust half decides).
class HdNimbusMesh final : public HdMesh {
public:
    explicit HdNimbusMesh(SdfPath const &id) : HdMesh(id) {}
    HdDirtyBits GetInitialDirtyBitsMask() const override;
    void Sync(HdSceneDelegate *delegate, HdRenderParam *param, HdDirtyBits *dirtyBits,
              TfToken const &reprToken) override;
    void Finalize(HdRenderParam *param) override;

protected:
    HdDirtyBits _PropagateDirtyBits(HdDirtyBits bits) const override { return bits; }
    void _InitRepr(TfToken const &reprToken, HdDirtyBits *dirtyBits) override {}
    TfTokenVector const &GetBuiltinPrimvarNames() const override;
};

// A light sprim of any Hydra light type; the types the core lacks are recorded as such
// (the render warns about them).
class HdNimbusLight final : public HdLight {
public:
    HdNimbusLight(SdfPath const &id, TfToken const &type) : HdLight(id), _type(type) {}
    void Sync(HdSceneDelegate *delegate, HdRenderParam *param,
              HdDirtyBits *dirtyBits) override;
    HdDirtyBits GetInitialDirtyBitsMask() const override { return AllDirty; }
    void Finalize(HdRenderParam *param) override;

private:
    TfToken _type;
};

// A field bprim (openvdbAsset; other field types are recorded so the volume naming one
// fails with a message).
class HdNimbusField final : public HdField {
public:
    HdNimbusField(SdfPath const &id, TfToken const &type) : HdField(id), _type(type) {}
    void Sync(HdSceneDelegate *delegate, HdRenderParam *param,
              HdDirtyBits *dirtyBits) override;
    HdDirtyBits GetInitialDirtyBitsMask() const override { return AllDirty; }
    void Finalize(HdRenderParam *param) override;

private:
    TfToken _type;
};

// A material sprim: its volume shader (PxrVolume, ND_anisotropic_vdf) and parameters.
class HdNimbusMaterial final : public HdMaterial {
public:
    explicit HdNimbusMaterial(SdfPath const &id) : HdMaterial(id) {}
    void Sync(HdSceneDelegate *delegate, HdRenderParam *param,
              HdDirtyBits *dirtyBits) override;
    HdDirtyBits GetInitialDirtyBitsMask() const override { return AllDirty; }
    void Finalize(HdRenderParam *param) override;
};

// A prim's transform samples as its scene delegate hands them over
// (`SampleTransform`: times in time codes from the frame).
rust::Vec<nimbus_hydra::XformSample> HdNimbusSampleTransform(HdSceneDelegate *delegate,
                                                             SdfPath const &id);

// A camera: HdCamera's parameters (the shutter among them) and its transform samples
// over the shutter (the render pass hands both to Rust).
class HdNimbusCamera final : public HdCamera {
public:
    explicit HdNimbusCamera(SdfPath const &id) : HdCamera(id) {}
    void Sync(HdSceneDelegate *delegate, HdRenderParam *param,
              HdDirtyBits *dirtyBits) override;
    rust::Vec<nimbus_hydra::XformSample> const &GetTransformSamples() const {
        return _samples;
    }

private:
    rust::Vec<nimbus_hydra::XformSample> _samples;
};

// A render settings prim: its shutter interval (Hydra's union of its products'
// camera shutters), the shutter when the camera's is closed.
class HdNimbusRenderSettings final : public HdRenderSettings {
public:
    explicit HdNimbusRenderSettings(SdfPath const &id) : HdRenderSettings(id) {}
    void Finalize(HdRenderParam *param) override;

protected:
    void _Sync(HdSceneDelegate *delegate, HdRenderParam *param,
               HdDirtyBits const *dirtyBits) override;
};

PXR_NAMESPACE_CLOSE_SCOPE

#endif
