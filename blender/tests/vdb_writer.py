"""A tiny OpenVDB writer for the tests: dense float and Vec3s grids, uncompressed, file
format 224 — the layout of Nimbus' own writer (src/volume/vdb/writer.rs, what OpenVDB
10's io::File writes with compression off): a Tree_float_5_4_3 or Tree_vec3s_5_4_3 of
leaves only, every node value written, a (Uniform)ScaleTranslateMap. bpy 5.0.1 has no
`openvdb` Python module, and the motion blur tests need a Vec3s velocity grid.

A grid is a dense numpy array, (nx, ny, nz) for a float grid or (nx, ny, nz, 3) for a
Vec3s one, its voxel (i, j, k) at index (i, j, k) and world point translation + voxel
* (i, j, k). Every voxel of the array is active (the array is padded with inactive
zeros to whole 8^3 leaves)."""

import struct

import numpy as np

MAGIC = bytes([0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0])
FILE_VERSION = 224
# Node metadata byte: every value follows, no mask compression.
NO_MASK_AND_ALL_VALS = 6


class _Out:
    def __init__(self):
        self.b = bytearray()

    def u8(self, v):
        self.b += struct.pack("<B", v)

    def u32(self, v):
        self.b += struct.pack("<I", v)

    def i32(self, v):
        self.b += struct.pack("<i", v)

    def i64(self, v):
        self.b += struct.pack("<q", v)

    def dvec3(self, v):
        self.b += struct.pack("<3d", *v)

    def string(self, s):
        data = s.encode()
        self.u32(len(data))
        self.b += data

    def mask(self, bits):
        """Bits (bool array, length a multiple of 64) as little-endian u64 words."""
        self.b += np.packbits(np.asarray(bits, bool), bitorder="little").tobytes()

    def meta(self, name, kind, payload):
        self.string(name)
        self.string(kind)
        if kind == "string":
            self.string(payload)
        else:
            self.u32(len(payload))
            self.b += payload


def _leaves(values, channels):
    """{leaf origin (x, y, z): (values (512, channels) in OpenVDB's x-major offset
    order, active bits (512,))} of the dense array."""
    shape = values.shape[:3]
    padded = [(-(-n // 8)) * 8 for n in shape]
    data = np.zeros(padded + [channels], np.float32)
    data[:shape[0], :shape[1], :shape[2]] = values.reshape(shape + (channels,))
    active = np.zeros(padded, bool)
    active[:shape[0], :shape[1], :shape[2]] = True
    out = {}
    for x in range(0, padded[0], 8):
        for y in range(0, padded[1], 8):
            for z in range(0, padded[2], 8):
                # offset = (x & 7) << 6 | (y & 7) << 3 | (z & 7): C order of [x, y, z].
                v = data[x:x + 8, y:y + 8, z:z + 8].reshape(512, channels)
                a = active[x:x + 8, y:y + 8, z:z + 8].reshape(512)
                out[(x, y, z)] = (v, a)
    return out, shape


def _idx5(p):
    f = [((c & 4095) >> 7) for c in p]
    return (f[0] << 10) | (f[1] << 5) | f[2]


def _idx4(p):
    f = [((c & 127) >> 3) for c in p]
    return (f[0] << 8) | (f[1] << 4) | f[2]


def _grid(out, name, values, voxel, translation, grid_class):
    values = np.asarray(values, np.float32)
    channels = 3 if values.ndim == 4 else 1
    if values.ndim == 4 and values.shape[3] != 3:
        raise ValueError(f"grid {name}: a vector grid's last axis must be 3")
    leaves, shape = _leaves(values, channels)
    if max(shape) > 4096:
        raise ValueError(f"grid {name}: larger than one 4096^3 root child")
    # One root child at (0, 0, 0); its 128^3 children keyed by their index.
    nodes4 = {}
    for origin in leaves:
        nodes4.setdefault(_idx5(origin), {})[_idx4(origin)] = origin
    out.string(name)
    out.string("Tree_vec3s_5_4_3" if channels == 3 else "Tree_float_5_4_3")
    out.string("")  # instance parent
    offsets_at = len(out.b)
    out.i64(0)
    out.i64(0)
    out.i64(0)
    grid_pos = len(out.b)
    out.u32(0)  # compression: none
    out.u32(6)
    out.meta("class", "string", grid_class)
    out.meta("name", "string", name)
    out.meta("file_voxel_count", "int64", struct.pack("<q", int(np.prod(shape))))
    out.meta("is_saved_as_half_float", "bool", b"\x00")
    out.meta("file_bbox_min", "vec3i", struct.pack("<3i", 0, 0, 0))
    out.meta("file_bbox_max", "vec3i", struct.pack("<3i", *(n - 1 for n in shape)))
    scale = np.broadcast_to(np.asarray(voxel, float), (3,))
    out.string("UniformScaleTranslateMap" if len(set(scale)) == 1 else "ScaleTranslateMap")
    out.dvec3(translation)
    out.dvec3(scale)
    out.dvec3(scale)
    out.dvec3(1.0 / scale)
    out.dvec3(1.0 / (scale * scale))
    out.dvec3(1.0 / (2.0 * scale))
    # Topology: buffer count, background, root tiles and children.
    out.i32(1)
    for _ in range(channels):
        out.b += struct.pack("<f", 0.0)
    out.u32(0)
    out.u32(1)
    out.i32(0)
    out.i32(0)
    out.i32(0)

    def internal(size, children):
        bits = np.zeros(size, bool)
        bits[list(children)] = True
        out.mask(bits)
        out.mask(np.zeros(size, bool))
        out.u8(NO_MASK_AND_ALL_VALS)
        out.b += np.zeros(size * channels, np.float32).tobytes()

    order = []
    internal(32768, nodes4.keys())
    for i5 in sorted(nodes4):
        internal(4096, nodes4[i5].keys())
        for i4 in sorted(nodes4[i5]):
            origin = nodes4[i5][i4]
            order.append(origin)
            out.mask(leaves[origin][1])
    block_pos = len(out.b)
    for origin in order:
        v, a = leaves[origin]
        out.mask(a)
        out.u8(NO_MASK_AND_ALL_VALS)
        out.b += np.ascontiguousarray(v, np.float32).tobytes()
    end_pos = len(out.b)
    out.b[offsets_at:offsets_at + 24] = struct.pack("<3q", grid_pos, block_pos, end_pos)


def write_vdb(path, grids):
    """Writes `grids`, a list of (name, array, voxel size, translation, class), to
    `path`."""
    out = _Out()
    out.b += MAGIC
    out.u32(FILE_VERSION)
    out.u32(10)
    out.u32(0)
    out.u8(1)  # has grid offsets
    out.b += b"6e696d62-7573-4d6f-8074-696f6e626c72"  # a UUID (36 characters)
    out.u32(0)  # file metadata entries
    out.i32(len(grids))
    for name, values, voxel, translation, grid_class in grids:
        _grid(out, name, values, voxel, translation, grid_class)
    with open(path, "wb") as f:
        f.write(bytes(out.b))
