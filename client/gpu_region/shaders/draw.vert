// skinserve-gpu-region's vertex shader: the server's float32 positions (and normals)
// straight from the GPU region, through one transform (vertex_renderer.h).
#version 450
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(push_constant) uniform Draw {
  mat4 transform;
  float point_size;
  float has_normals;
} draw;
layout(location = 0) out vec3 v_normal;
void main() {
  gl_Position = draw.transform * vec4(position, 1.0);
  gl_PointSize = draw.point_size;
  v_normal = normal;
}
