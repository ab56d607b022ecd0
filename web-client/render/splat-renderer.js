// Draws the splats as lit, oriented discs: two triangles per point, turned to face along the
// point's normal, cut to a circle in the fragment shader. The vertex shader reads its point
// from the splat texture by vertex id (render/splat-buffer.js): vertex v belongs to point
// floor(v / 6) and is corner v % 6 of its quad.
// Conventions: world in vu, y up; a disc's radius is DISC_RADIUS vu, a little over half the
// voxel spacing so that the discs of neighbouring voxels overlap without holes at any zoom
// (the splat size follows perspective because the discs are real geometry, and the depth
// buffer holds each disc's true plane). Discs whose normal faces clearly away from the eye are
// dropped in the vertex shader (the front side of a closed surface hides them anyway).

import { CLAY_GLSL, createProgram } from "./gl-program.js";
import { SplatBuffer, TEXTURE_WIDTH } from "./splat-buffer.js";

export const DISC_RADIUS = 0.8;
// Discs turned away from the eye by up to this cosine are still drawn: at the silhouette they
// fill the gaps between the thin ellipses of the discs seen edge-on.
const BACK_FACING = 0.25;

const VERTEX = `#version 300 es
uniform highp usampler2D u_points;
uniform mat4 u_viewProjection;
uniform vec3 u_eye;
uniform float u_radius;
out vec3 v_normal;
out vec3 v_toEye;
out vec2 v_corner;
const float BACK_FACING = ${BACK_FACING.toFixed(3)};
// An equilateral triangle around the unit circle: three vertices per disc, half of a quad's six.
const vec2 CORNERS[3] = vec2[3](vec2(0.0, 2.0), vec2(-1.7320508, -1.0), vec2(1.7320508, -1.0));
void main() {
  int point = gl_VertexID / 3;
  uvec4 texel = texelFetch(u_points, ivec2(point % ${TEXTURE_WIDTH}, point / ${TEXTURE_WIDTH}), 0);
  vec3 position = uintBitsToFloat(texel.xyz);
  uint packed = texel.w;
  vec3 n = (vec3(packed & 1023u, (packed >> 10) & 1023u, (packed >> 20) & 1023u) - 512.0) / 511.0;
  if ((packed & ${1 << 30}u) == 0u || dot(n, normalize(u_eye - position)) < -BACK_FACING) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0); // outside the clip volume: no fragments
    return;
  }
  n = normalize(n);
  vec2 corner = CORNERS[gl_VertexID - 3 * point];
  vec3 helper = abs(n.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
  vec3 t = normalize(cross(helper, n));
  vec3 b = cross(n, t);
  vec3 p = position + u_radius * (corner.x * t + corner.y * b);
  v_normal = n;
  v_toEye = u_eye - p;
  v_corner = corner;
  gl_Position = u_viewProjection * vec4(p, 1.0);
}`;

const FRAGMENT = `#version 300 es
precision highp float;
in vec3 v_normal;
in vec3 v_toEye;
in vec2 v_corner;
uniform vec3 u_light;
uniform vec3 u_up;
uniform int u_shading; // 0 clay, 1 normals
out vec4 outColor;
${CLAY_GLSL}
void main() {
  if (dot(v_corner, v_corner) > 1.0) discard;
  vec3 n = normalize(v_normal);
  if (u_shading == 1) {
    outColor = vec4(0.5 * n + 0.5, 1.0);
    return;
  }
  outColor = vec4(toSrgb(clay(n, normalize(v_toEye), u_light, u_up)), 1.0);
}`;

export class SplatRenderer {
  constructor(gl) {
    this.gl = gl;
    this.buffer = new SplatBuffer(gl);
    this.#init();
  }

  #init() {
    const gl = this.gl;
    this.program = createProgram(gl, VERTEX, FRAGMENT, ["u_points", "u_viewProjection", "u_eye", "u_radius", "u_light", "u_up", "u_shading"]);
    this.vao = gl.createVertexArray(); // no attributes: everything comes from the texture
  }

  // The context came back: new GL objects; the store must upload everything again.
  restore(store) {
    this.buffer.lost();
    this.#init();
    store.requestRepack();
  }

  // Brings the GPU copy up to date with the store (cheap when nothing changed).
  sync(store) {
    this.buffer.sync(store);
    this.pointCount = Math.min(store.slotCount, this.buffer.capacity);
  }

  // camera: math/orbit-camera.js after update(); shading: "lit" or "normals".
  draw(camera, shading) {
    if (!this.pointCount || !this.buffer.texture) return;
    const gl = this.gl;
    const { program, uniforms } = this.program;
    gl.useProgram(program);
    gl.bindVertexArray(this.vao);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.buffer.texture);
    gl.uniform1i(uniforms.u_points, 0);
    gl.uniformMatrix4fv(uniforms.u_viewProjection, false, camera.viewProjection);
    gl.uniform3fv(uniforms.u_eye, camera.eye);
    gl.uniform1f(uniforms.u_radius, DISC_RADIUS);
    gl.uniform3fv(uniforms.u_light, keyLight(camera));
    gl.uniform3fv(uniforms.u_up, camera.up);
    gl.uniform1i(uniforms.u_shading, shading === "normals" ? 1 : 0);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LEQUAL);
    gl.depthMask(true);
    gl.drawArrays(gl.TRIANGLES, 0, 3 * this.pointCount);
    gl.bindVertexArray(null);
  }
}

// Towards the key light, from the camera's upper left, as the server's ray caster has it.
function keyLight(camera) {
  const r = camera.right, u = camera.up, b = camera.backward;
  const l = [0, 1, 2].map((k) => -0.45 * r[k] + 0.65 * u[k] + 0.6 * b[k]);
  const len = Math.hypot(...l);
  return l.map((v) => v / len);
}
