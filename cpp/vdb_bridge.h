// OpenVDB → plain buffers. The only C++ in Nimbus: it opens a file with OpenVDB and
// copies a float or Vec3s grid's leaves, tiles and transform into Rust-owned vectors. All
// validation and all interpretation happen on the Rust side.
#pragma once

#include "rust/cxx.h"

#include <cstdint>

namespace nimbus_vdb {

struct GridListEntry;
struct GridData;

// Grids of a file, in OpenVDB's order, from metadata only (no trees are read).
rust::Vec<GridListEntry> list_grids(rust::Str path);

// Reads the grid `lookup_name` ("name" or "name[N]" for the N-th duplicate, as
// OpenVDB's File::readGrid understands it) and copies it out. Throws (→ Rust Err)
// unless it is a float grid with a linear transform.
GridData read_float_grid(rust::Str path, rust::Str lookup_name);

// As read_float_grid, for a Vec3s grid (three floats per value, also when the file
// stores halves).
GridData read_vec3s_grid(rust::Str path, rust::Str lookup_name);

// OpenVDB's in-memory size in bytes (GridBase::memUsage) of the float grid `lookup_name`,
// as read_float_grid reads it; for benchmarks.
uint64_t float_grid_mem_usage(rust::Str path, rust::Str lookup_name);

} // namespace nimbus_vdb
