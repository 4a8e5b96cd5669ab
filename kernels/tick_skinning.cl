/* A tick's characters in one launch (opencl_tick_launch.h): linear blending of float32
 * meshes that live in the device mesh arena (opencl_mesh_arena.h), each character with its
 * own mesh, palette and outputs. Dimension 1 of the NDRange is the character, dimension 0
 * its vertices in the single-frame kernels' order (SKIN_VERTEX, or the *_local_* kernels'
 * tiles), sized for the launch's largest mesh: a character's items past its own vertex
 * count return. Character c's row of `table` (TICK_FIELDS uints) says where its arrays
 * are, in 4-byte words: the mesh's in `arena`, its palette in `palettes`, its outputs in
 * `out`. The bodies are the single-frame kernels' own (skinning_common.cl and
 * linear_blend_skinning.cl, built before this file), so a character's vertices come out
 * exactly as its frame alone would. */

/* A row: vertex count, palette, joints, weights, positions, out positions, normals, out
 * normals, tangents, out tangents (offsets in words; the arrays a launch does not write
 * are 0), palette floats (the *_local_* kernels stage that many). */
#define TICK_FIELDS 11

/* The launch's characters are rows first_row, first_row + 1, ... of `table` (one table
 * for a whole batch's launches). */
#define TICK_ARGS                                                                          \
  const __global uint *restrict arena, const __global uint *restrict table,                \
      const __global float *restrict palettes, __global float *restrict out,               \
      const uint first_row

/* The names the bodies use, for this item's character. */
#define TICK_CHARACTER                                                                     \
  const __global uint* restrict row =                                                      \
      table + TICK_FIELDS * (first_row + (uint)get_global_id(1));                          \
  const uint vertex_count = row[0];                                                        \
  const __global float* restrict palette = palettes + row[1];                              \
  const __global ushort* restrict joints = (const __global ushort*)(arena + row[2]);      \
  const __global float* restrict weights = (const __global float*)(arena + row[3]);       \
  const __global float* restrict positions = (const __global float*)(arena + row[4]);     \
  __global float* restrict out_positions = out + row[5];                                   \
  const __global float* restrict normals = (const __global float*)(arena + row[6]);       \
  __global float* restrict out_normals = out + row[7];                                     \
  const __global float* restrict tangents = (const __global float*)(arena + row[8]);      \
  __global float* restrict out_tangents = out + row[9];                                    \
  const uint palette_floats = row[10];                                                     \
  (void)normals, (void)out_normals, (void)tangents, (void)out_tangents, (void)palette_floats;

/* tick_bB, tick_normals_bB, tick_tangents_bB. */
#define DEFINE_TICK_KERNELS(B)                                                             \
  __kernel void tick_b##B(TICK_ARGS) {                                                     \
    TICK_CHARACTER                                                                         \
    SKIN_POSITIONS_BODY(B, BlendPalette, palette, SKIN_VERTEX, StorePosition)              \
  }                                                                                        \
  __kernel void tick_normals_b##B(TICK_ARGS) {                                             \
    TICK_CHARACTER                                                                         \
    SKIN_NORMALS_BODY(B, BlendPalette, palette, SKIN_VERTEX, StorePosition, SKIN_NORMAL,   \
                      SKIN_NO_TANGENTS_PREPARE, SKIN_TRANSFORM_TANGENT, SKIN_NO_TANGENT)   \
  }                                                                                        \
  __kernel void tick_tangents_b##B(TICK_ARGS) {                                            \
    TICK_CHARACTER                                                                         \
    SKIN_NORMALS_BODY(B, BlendPalette, palette, SKIN_VERTEX, StorePosition, SKIN_NORMAL,   \
                      SKIN_TANGENTS_PREPARE_OF, SKIN_TRANSFORM_TANGENT, SKIN_TANGENT)      \
  }                                                                                        \
  DEFINE_LOCAL_TICK_KERNELS(B)

#if SKIN_LOCAL_PALETTE
/* tick_local_bB, ...: the palette staged in local memory first, as skin_local_bB does.
 * `staged` is sized by the host for the launch's largest palette; every item of a group
 * (one character: dimension 1's group size is 1) reaches the barrier before any returns. */
#define DEFINE_LOCAL_TICK_KERNELS(B)                                                       \
  __kernel void tick_local_b##B(TICK_ARGS, __local float4 *restrict staged) {              \
    TICK_CHARACTER                                                                         \
    SKIN_TILES_BEGIN                                                                       \
    SKIN_POSITIONS_BODY(B, BlendLocalPalette, staged, SKIN_TILE_VERTEX, StorePosition)     \
    SKIN_TILES_END                                                                         \
  }                                                                                        \
  __kernel void tick_normals_local_b##B(TICK_ARGS, __local float4 *restrict staged) {      \
    TICK_CHARACTER                                                                         \
    SKIN_TILES_BEGIN                                                                       \
    SKIN_NORMALS_BODY(B, BlendLocalPalette, staged, SKIN_TILE_VERTEX, StorePosition,       \
                      SKIN_NORMAL, SKIN_NO_TANGENTS_PREPARE, SKIN_TRANSFORM_TANGENT,       \
                      SKIN_NO_TANGENT)                                                     \
    SKIN_TILES_END                                                                         \
  }                                                                                        \
  __kernel void tick_tangents_local_b##B(TICK_ARGS, __local float4 *restrict staged) {     \
    TICK_CHARACTER                                                                         \
    SKIN_TILES_BEGIN                                                                       \
    SKIN_NORMALS_BODY(B, BlendLocalPalette, staged, SKIN_TILE_VERTEX, StorePosition,       \
                      SKIN_NORMAL, SKIN_TANGENTS_PREPARE_OF, SKIN_TRANSFORM_TANGENT,       \
                      SKIN_TANGENT)                                                        \
    SKIN_TILES_END                                                                         \
  }
#else
#define DEFINE_LOCAL_TICK_KERNELS(B)
#endif

DEFINE_TICK_KERNELS(1)
DEFINE_TICK_KERNELS(2)
DEFINE_TICK_KERNELS(3)
DEFINE_TICK_KERNELS(4)
DEFINE_TICK_KERNELS(5)
DEFINE_TICK_KERNELS(6)
DEFINE_TICK_KERNELS(7)
DEFINE_TICK_KERNELS(8)
