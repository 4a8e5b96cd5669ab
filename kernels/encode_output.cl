// Encoded output on the device (opencl_encode.cpp): a frame's skinned floats, already in
// device buffers, become the bytes core/encoding's EncodePositions / EncodeNormals /
// EncodeTangents make of them, so that only those (half the bytes) cross back to the host.
// Every formula is the host encoder's, written with the same float operations in the same
// order (IEEE single add and multiply are exact-rounded in OpenCL; no contraction): the
// bytes are identical. A value the encoding refuses only raises `bad`; the host then names
// it with the host encoder's own error.
#pragma OPENCL FP_CONTRACT OFF

#define ENCODE_GROUP 256

// Per work-group: the min and max of x y z over the vertices the group strides over, and
// whether one of its values is not finite: partial[8 g ..] = min xyz, max xyz, non-finite
// count, 0. The host combines the groups' rows (few: the grid is capped).
__kernel __attribute__((reqd_work_group_size(ENCODE_GROUP, 1, 1))) void bounds_partial(
    __global const float* positions, uint vertex_count, __global float* partial) {
  __local float lo[3][ENCODE_GROUP], hi[3][ENCODE_GROUP];
  __local uint bad[ENCODE_GROUP];
  const uint lid = get_local_id(0);
  float l0 = INFINITY, l1 = INFINITY, l2 = INFINITY;
  float h0 = -INFINITY, h1 = -INFINITY, h2 = -INFINITY;
  uint not_finite = 0;
  for (uint v = get_global_id(0); v < vertex_count; v += get_global_size(0)) {
    const float x = positions[3 * v], y = positions[3 * v + 1], z = positions[3 * v + 2];
    not_finite |= !isfinite(x) | !isfinite(y) | !isfinite(z);
    l0 = fmin(l0, x);
    l1 = fmin(l1, y);
    l2 = fmin(l2, z);
    h0 = fmax(h0, x);
    h1 = fmax(h1, y);
    h2 = fmax(h2, z);
  }
  lo[0][lid] = l0;
  lo[1][lid] = l1;
  lo[2][lid] = l2;
  hi[0][lid] = h0;
  hi[1][lid] = h1;
  hi[2][lid] = h2;
  bad[lid] = not_finite;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint step = ENCODE_GROUP / 2; step > 0; step /= 2) {
    if (lid < step) {
      for (int a = 0; a < 3; ++a) {
        lo[a][lid] = fmin(lo[a][lid], lo[a][lid + step]);
        hi[a][lid] = fmax(hi[a][lid], hi[a][lid + step]);
      }
      bad[lid] |= bad[lid + step];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lid == 0) {
    __global float* row = partial + 8 * get_group_id(0);
    for (int a = 0; a < 3; ++a) {
      row[a] = lo[a][0];
      row[3 + a] = hi[a][0];
    }
    row[6] = (float)bad[0];
    row[7] = 0.0f;
  }
}

// snorm16 positions: q = round_even(clamp((x - centre) * scale, -32767, 32767)), per axis
// (value i is axis i % 3); scale = 32767 / half-extent computed on the host exactly as
// core/encoding's AxesOf (0 for an empty axis). The box holds every value by construction.
__kernel void encode_snorm16_positions(__global const float* in, uint count, float c0, float c1,
                                       float c2, float s0, float s1, float s2,
                                       __global short* out) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const uint a = i % 3;
  const float c = a == 0 ? c0 : (a == 1 ? c1 : c2);
  const float s = a == 0 ? s0 : (a == 1 ? s1 : s2);
  const float t = fmin(fmax((in[i] - c) * s, -32767.0f), 32767.0f);
  out[i] = (short)rint(t);
}

// snorm16 unit values (normals, tangents' x y z w): q = round_even(n * 32767); |n * 32767|
// must stay below 32767.5 (else `bad`).
__kernel void encode_snorm16_unit(__global const float* in, uint count, __global short* out,
                                  __global int* bad) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const float t = in[i] * 32767.0f;
  if (!(fabs(t) < 32767.5f)) *bad = 1;
  out[i] = (short)rint(fmin(fmax(t, -32767.0f), 32767.0f));
}

// float16, round to nearest even: core/encoding's HalfBitsOfFinite (F. Giesen's
// float_to_half_fast3_rtne) step by step, so that no device's own conversion (or its
// denormal handling) decides a bit. |x| beyond 65504 or not finite: `bad`.
__kernel void encode_half(__global const float* in, uint count, __global ushort* out,
                          __global int* bad) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const float value = in[i];
  if (!(fabs(value) <= 65504.0f)) *bad = 1;
  const uint denorm_magic = 126u << 23;  // 0.5f
  const uint bits = as_uint(value);
  const uint sign = (bits >> 16) & 0x8000u;
  const uint magnitude = bits & 0x7fffffffu;
  const uint subnormal = as_uint(as_float(magnitude) + as_float(denorm_magic)) - denorm_magic;
  const uint odd = (magnitude >> 13) & 1u;
  const uint normal = (magnitude - ((127u - 15u) << 23) + 0xfffu + odd) >> 13;
  const uint half_bits = magnitude < (113u << 23) ? subnormal : normal;
  out[i] = (ushort)(half_bits | sign);
}
