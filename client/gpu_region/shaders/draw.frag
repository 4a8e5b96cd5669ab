// One light from the viewer's upper left on the normals when the region has them; a flat
// colour otherwise (a point cloud without normals).
#version 450
layout(location = 0) in vec3 v_normal;
layout(push_constant) uniform Draw {
  mat4 transform;
  float point_size;
  float has_normals;
} draw;
layout(location = 0) out vec4 color;
void main() {
  vec3 base = vec3(0.90, 0.62, 0.36);
  float shade = 1.0;
  if (draw.has_normals > 0.5) {
    vec3 n = normalize(v_normal);
    shade = 0.35 + 0.65 * abs(dot(n, normalize(vec3(-0.4, 0.6, 0.7))));
  }
  color = vec4(base * shade, 1.0);
}
