#include "nimbus/cpp/vdb_bridge.h"
#include "nimbus/cpp/guarded.h"
#include "nimbus/src/volume/vdb/bridge.rs.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <exception>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

namespace nimbus_vdb {
namespace {

// openvdb::Exception derives from std::exception: guarded() turns it into a capped error.
template <typename F>
auto guarded(F&& body) -> decltype(body()) {
    return nimbus_cpp::guarded("OpenVDB", std::forward<F>(body));
}

void open_file(openvdb::io::File& file) {
    openvdb::initialize();
    // Delayed loading would keep the file mapped and read leaves lazily; we copy
    // everything out at once, so read eagerly.
    file.setCopyMaxBytes(0);
    file.open(/*delayLoad=*/false);
}

template <typename Vec, typename T>
void push3(Vec& v, const T& c) {
    v.push_back(c[0]);
    v.push_back(c[1]);
    v.push_back(c[2]);
}

void push_value(rust::Vec<float>& v, float x) { v.push_back(x); }
size_t leaf_values_len(size_t leaves, float) { return leaves * 512; }
size_t leaf_values_len(size_t leaves, const openvdb::Vec3s&) { return leaves * 512 * 3; }
void push_value(rust::Vec<float>& v, const openvdb::Vec3s& x) { push3(v, x); }

template <typename Value>
void push_tile(GridData& out, const Value& background, const openvdb::Coord& origin, int32_t dim,
               const Value& value, bool active) {
    // Inactive tiles that hold the background carry no information; Rust readers
    // apply the same rule so both produce the same tile lists.
    if (!active && value == background) return;
    push3(out.tile_origins, origin);
    out.tile_dims.push_back(dim);
    push_value(out.tile_values, value);
    out.tile_active.push_back(active ? 1 : 0);
}

// Reads grid `name` of `path` as a `GridT`; throws unless it is one, with a linear
// transform. `type_label` names the expected type in the error.
template <typename GridT>
typename GridT::Ptr read_grid(rust::Str path, const std::string& name, const char* type_label) {
    openvdb::io::File file{std::string(path)};
    open_file(file);
    if (!file.hasGrid(name)) {
        throw std::runtime_error("grid " + name + " not found");
    }
    openvdb::GridBase::Ptr base = file.readGrid(name);
    file.close();
    if (!base) throw std::runtime_error("grid " + name + " could not be read");
    if (std::is_same<GridT, openvdb::FloatGrid>::value && base->isType<openvdb::Vec3SGrid>()) {
        throw std::runtime_error("grid " + name + " is Vec3s, expected float");
    }
    typename GridT::Ptr grid = openvdb::gridPtrCast<GridT>(base);
    if (!grid) {
        throw std::runtime_error("grid " + name + " is " + base->valueType() + ", expected " +
                                 type_label);
    }
    const openvdb::math::MapBase::ConstPtr map = grid->transform().baseMap();
    if (!map->isLinear()) {
        throw std::runtime_error("grid " + name + " has a non-linear transform (" +
                                 map->type() + "); only affine transforms are supported");
    }
    return grid;
}

// Copies name, class, transform, tiles and leaves of `grid` into `out`: one float
// per value for a float grid, three for a Vec3s grid.
template <typename GridT>
void copy_grid(const GridT& grid, GridData& out) {
    out.name = grid.getName();
    out.class_name = openvdb::GridBase::gridClassToString(grid.getGridClass());
    const auto background = grid.background();
    push_value(out.background, background);

    // OpenVDB's matrices are row-vector (world = [i j k 1] * M); copy row-major and
    // let Rust transpose.
    const openvdb::math::Mat4d m = grid.transform().baseMap()->getAffineMap()->getMat4();
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) out.index_to_world_row_major.push_back(m(r, c));

    const auto& root = grid.tree().root();
    for (auto it = root.cbeginValueAll(); it; ++it) {
        push_tile(out, background, it.getCoord(), 4096, *it, it.isValueOn());
    }
    using LeafT = typename GridT::TreeType::LeafNodeType;
    const size_t leaf_count = grid.tree().leafCount();
    out.leaf_origins.reserve(leaf_count * 3);
    out.leaf_masks.reserve(leaf_count * 8);
    out.leaf_values.reserve(leaf_values_len(leaf_count, background));
    for (auto c5 = root.cbeginChildOn(); c5; ++c5) {
        for (auto it = c5->cbeginValueAll(); it; ++it) {
            push_tile(out, background, it.getCoord(), 128, *it, it.isValueOn());
        }
        for (auto c4 = c5->cbeginChildOn(); c4; ++c4) {
            for (auto it = c4->cbeginValueAll(); it; ++it) {
                push_tile(out, background, it.getCoord(), 8, *it, it.isValueOn());
            }
            for (auto leaf = c4->cbeginChildOn(); leaf; ++leaf) {
                push3(out.leaf_origins, leaf->origin());
                for (openvdb::Index i = 0; i < LeafT::SIZE; ++i) {
                    push_value(out.leaf_values, leaf->getValue(i));
                }
                const auto& mask = leaf->getValueMask();
                for (openvdb::Index w = 0; w < 8; ++w) {
                    out.leaf_masks.push_back(mask.template getWord<uint64_t>(w));
                }
            }
        }
    }
}

} // namespace

rust::Vec<GridListEntry> list_grids(rust::Str path) {
    return guarded([&] {
        openvdb::io::File file{std::string(path)};
        open_file(file);
        rust::Vec<GridListEntry> out;
        openvdb::GridPtrVecPtr grids = file.readAllGridMetadata();
        // Both iterate the file's descriptor table in the same order; the iterator
        // supplies names for grids whose metadata lacks a "name" entry.
        auto names = file.beginName();
        for (const auto& g : *grids) {
            std::string fallback;
            if (names != file.endName()) {
                fallback = names.gridName();
                ++names;
            }
            if (!g) continue;
            GridListEntry e;
            e.name = g->getName().empty() ? fallback : g->getName();
            e.value_type = g->type();
            e.active_voxels = -1;
            if (auto m = g->getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_VOXEL_COUNT)) {
                e.active_voxels = m->value();
            }
            out.push_back(std::move(e));
        }
        file.close();
        return out;
    });
}

GridData read_float_grid(rust::Str path, rust::Str lookup_name) {
    return guarded([&] {
        auto grid = read_grid<openvdb::FloatGrid>(path, std::string(lookup_name), "float");
        GridData out;
        copy_grid(*grid, out);
        return out;
    });
}

GridData read_vec3s_grid(rust::Str path, rust::Str lookup_name) {
    return guarded([&] {
        // Half-float storage is converted to Vec3s by OpenVDB on read.
        auto grid = read_grid<openvdb::Vec3SGrid>(path, std::string(lookup_name), "Vec3s");
        GridData out;
        copy_grid(*grid, out);
        return out;
    });
}

uint64_t float_grid_mem_usage(rust::Str path, rust::Str lookup_name) {
    return guarded([&] {
        auto grid = read_grid<openvdb::FloatGrid>(path, std::string(lookup_name), "float");
        return static_cast<uint64_t>(grid->memUsage());
    });
}

} // namespace nimbus_vdb
