// Draws the splats as lit, oriented discs: two triangles per point, turned to face along the
// point's normal, cut to a circle in the fragment shader. The vertex shader reads its point
// from the splat texture by vertex id (render/splat-buffer.js): vertex v belongs to point
// floor(v / 6) and is corner v % 6 of its quad.
// Conventions: world in vu, y up; a disc's radius is DISC_RADIUS vu (render/splat-store.js),
// a little over half the voxel spacing so that the discs of neighbouring voxels overlap
// without holes at any zoom (the splat size follows perspective because the discs are real
// geometry, and the depth buffer holds each disc's true plane). A disc's normal may vary
// linearly across it (math/splat-shading.js, "Phong splatting"): then its second texel holds
// the gradient, and the vertex shader gives each corner the normal there, which the
// interpolation carries exactly over the flat disc; where the surface bends fast (rims) the
// discs then shade as one smooth surface instead of a row of beads. Discs whose normal faces
// clearly away from the eye are dropped in the vertex shader (the front side of a closed
// surface hides them anyway).
// Blending (where the GPU can render to half floats, EXT_color_buffer_float): drawn opaque,
// overlapping discs read as fish scales and sharp rims as strings of beads, since each pixel
// shows one disc's flat normal. So the discs are drawn in three passes instead: (1) depth only,
// each disc pushed BLEND_DEPTH vu away from the eye along its view ray (same pixels); (2) every
// disc within that depth of the nearest surface adds its normal weighted by (1 - r^2)^2 of its
// radius r into a half-float target (depth test against pass 1, additive blending); (3) a
// full-screen pass normalises the sum and shades it, so neighbouring discs blend into one
// smooth surface; their albedos (each point's colour in linear light, darker where masked) are
// summed alike into a second target and blended the same way. Without the
// extension the discs are drawn opaque, as before.

import { CLAY_GLSL, PAINT_GLSL, createProgram } from "./gl-program.js";
import { SplatBuffer, TEXTURE_WIDTH } from "./splat-buffer.js";
import { DISC_RADIUS } from "./splat-store.js";
import { MAX_GRADIENT } from "../math/splat-shading.js";

export { DISC_RADIUS };
// Discs turned away from the eye by up to this cosine are still drawn: at the silhouette they
// fill the gaps between the thin ellipses of the discs seen edge-on.
const BACK_FACING = 0.25;
// Discs within this depth (vu, along the view ray) of the nearest one blend: more than a disc's
// radius, so that the tilted discs of one surface meet, and well under the 2 vu of a thin wall.
const BLEND_DEPTH = 1.0;

const VERTEX = `#version 300 es
uniform highp usampler2D u_points;
uniform mat4 u_viewProjection;
uniform vec3 u_eye;
uniform float u_radius;
uniform float u_depthPush; // vu away from the eye along the view ray (the depth-only pass)
out vec3 v_normal;
out vec3 v_toEye;
out vec2 v_corner;
out vec3 v_albedo;
const float BACK_FACING = ${BACK_FACING.toFixed(3)};
// An equilateral triangle around the unit circle: three vertices per disc, half of a quad's six.
const vec2 CORNERS[3] = vec2[3](vec2(0.0, 2.0), vec2(-1.7320508, -1.0), vec2(1.7320508, -1.0));
${PAINT_GLSL}
vec3 unpack(uint packed) {
  return (vec3(packed & 1023u, (packed >> 10) & 1023u, (packed >> 20) & 1023u) - 512.0) / 511.0;
}
void main() {
  int point = gl_VertexID / 3;
  int first = 2 * point; // its two texels: first and first + 1, in one row
  ivec2 at = ivec2(first % ${TEXTURE_WIDTH}, first / ${TEXTURE_WIDTH});
  uvec4 texel = texelFetch(u_points, at, 0);
  vec3 position = uintBitsToFloat(texel.xyz);
  uint packed = texel.w;
  vec3 n = unpack(packed);
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
  uvec4 second = texelFetch(u_points, at + ivec2(1, 0), 0);
  v_albedo = paintAlbedo(vec4((uvec4(second.z) >> uvec4(0u, 8u, 16u, 24u)) & 255u) / 255.0);
  // The normal varies linearly over the disc (math/splat-shading.js): its value at the corner,
  // interpolated, is exact everywhere on the flat disc.
  if ((packed & ${2 ** 31}u) != 0u) {
    n += u_radius * ${MAX_GRADIENT.toFixed(1)} * (corner.x * unpack(second.x) + corner.y * unpack(second.y));
  }
  v_normal = n;
  v_toEye = u_eye - p;
  v_corner = corner;
  gl_Position = u_viewProjection * vec4(p + u_depthPush * normalize(p - u_eye), 1.0);
}`;

const FRAGMENT = `#version 300 es
precision highp float;
in vec3 v_normal;
in vec3 v_toEye;
in vec2 v_corner;
in vec3 v_albedo;
uniform vec3 u_light;
uniform vec3 u_up;
uniform int u_shading; // 0 clay, 1 normals, 2 the blended passes' weighted normal and albedo
layout(location = 0) out vec4 outColor;
layout(location = 1) out vec4 outAlbedo; // the blended passes only
${CLAY_GLSL}
void main() {
  float r2 = dot(v_corner, v_corner);
  if (r2 > 1.0) discard;
  vec3 n = normalize(v_normal);
  if (u_shading == 2) {
    float w = (1.0 - r2) * (1.0 - r2);
    outColor = vec4(w * n, w);
    outAlbedo = vec4(w * v_albedo, w);
    return;
  }
  outAlbedo = vec4(0.0);
  if (u_shading == 1) {
    outColor = vec4(0.5 * n + 0.5, 1.0);
    return;
  }
  outColor = vec4(toSrgb(clay(n, normalize(v_toEye), u_light, u_up, v_albedo)), 1.0);
}`;

// The resolve pass: one triangle over the viewport; the pixel's summed normal, shaded.
const RESOLVE_VERTEX = `#version 300 es
void main() {
  vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}`;

const RESOLVE_FRAGMENT = `#version 300 es
precision highp float;
uniform sampler2D u_sum;
uniform sampler2D u_albedo; // the weighted albedos, summed as the normals
uniform vec2 u_size;      // viewport, pixels
uniform vec2 u_tan;       // tan of the half field of view, horizontal and vertical
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec3 u_light;
uniform int u_shading;    // 0 clay, 1 normals
out vec4 outColor;
${CLAY_GLSL}
void main() {
  vec4 sum = texelFetch(u_sum, ivec2(gl_FragCoord.xy), 0);
  if (sum.w < 1e-4) discard;
  vec3 n = normalize(sum.xyz / sum.w);
  if (u_shading == 1) {
    outColor = vec4(0.5 * n + 0.5, 1.0);
    return;
  }
  vec2 s = (2.0 * gl_FragCoord.xy / u_size - 1.0) * u_tan;
  vec3 toEye = -normalize(u_forward + s.x * u_right + s.y * u_up);
  vec4 albedo = texelFetch(u_albedo, ivec2(gl_FragCoord.xy), 0);
  outColor = vec4(toSrgb(clay(n, toEye, u_light, u_up, albedo.rgb / albedo.w)), 1.0);
}`;

export class SplatRenderer {
  constructor(gl) {
    this.gl = gl;
    this.buffer = new SplatBuffer(gl);
    this.#init();
  }

  #init() {
    const gl = this.gl;
    this.program = createProgram(gl, VERTEX, FRAGMENT, ["u_points", "u_viewProjection", "u_eye", "u_radius", "u_depthPush", "u_light", "u_up", "u_shading"]);
    this.vao = gl.createVertexArray(); // no attributes: everything comes from the texture
    // Blending needs a renderable half-float target; `blend` may be set false to draw opaque.
    this.canBlend = Boolean(gl.getExtension("EXT_color_buffer_float"));
    if (this.blend === undefined) this.blend = this.canBlend;
    this.resolve = createProgram(gl, RESOLVE_VERTEX, RESOLVE_FRAGMENT, ["u_sum", "u_albedo", "u_size", "u_tan", "u_forward", "u_right", "u_up", "u_light", "u_shading"]);
    this.target = null; // {framebuffer, sum, albedo, depth, width, height} of the blended passes
  }

  // The blended passes' framebuffer at the drawing buffer's size: two half-float colour
  // textures for the sums (normals, albedos) and a depth buffer; made again when the size changes.
  #targetFor(width, height) {
    const gl = this.gl;
    if (this.target && this.target.width === width && this.target.height === height) return this.target;
    if (this.target) {
      gl.deleteFramebuffer(this.target.framebuffer);
      gl.deleteTexture(this.target.sum);
      gl.deleteTexture(this.target.albedo);
      gl.deleteRenderbuffer(this.target.depth);
    }
    const halfFloat = () => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA16F, width, height);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      return t;
    };
    const sum = halfFloat();
    const albedo = halfFloat();
    const depth = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, width, height);
    const framebuffer = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, framebuffer);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, sum, 0);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT1, gl.TEXTURE_2D, albedo, 0);
    gl.drawBuffers([gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1]);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    const complete = gl.checkFramebufferStatus(gl.FRAMEBUFFER) === gl.FRAMEBUFFER_COMPLETE;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    this.target = { framebuffer, sum, albedo, depth, width, height };
    if (!complete) this.canBlend = this.blend = false;
    return this.target;
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
    // (made before the points' texture is bound: making it binds its own texture)
    const width = gl.drawingBufferWidth, height = gl.drawingBufferHeight;
    const target = this.blend && this.canBlend ? this.#targetFor(width, height) : null;
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
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LEQUAL);
    if (!target || !this.blend) {
      gl.uniform1f(uniforms.u_depthPush, 0);
      gl.uniform1i(uniforms.u_shading, shading === "normals" ? 1 : 0);
      gl.depthMask(true);
      gl.drawArrays(gl.TRIANGLES, 0, 3 * this.pointCount);
      gl.bindVertexArray(null);
      return;
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, target.framebuffer);
    gl.colorMask(true, true, true, true);
    gl.depthMask(true); // a clear writes only what the masks allow
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    // 1: the nearest surface's depth, pushed back by BLEND_DEPTH
    gl.colorMask(false, false, false, false);
    gl.uniform1f(uniforms.u_depthPush, BLEND_DEPTH);
    gl.uniform1i(uniforms.u_shading, 2);
    gl.drawArrays(gl.TRIANGLES, 0, 3 * this.pointCount);
    // 2: the weighted normals of every disc in front of it
    gl.colorMask(true, true, true, true);
    gl.depthMask(false);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE);
    gl.uniform1f(uniforms.u_depthPush, 0);
    gl.drawArrays(gl.TRIANGLES, 0, 3 * this.pointCount);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    // 3: normalised and shaded over the backdrop (pixels no disc reached keep it)
    gl.disable(gl.BLEND);
    gl.disable(gl.DEPTH_TEST);
    gl.depthMask(true);
    const r = this.resolve;
    gl.useProgram(r.program);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, target.sum);
    gl.uniform1i(r.uniforms.u_sum, 0);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, target.albedo);
    gl.uniform1i(r.uniforms.u_albedo, 1);
    gl.activeTexture(gl.TEXTURE0);
    gl.uniform2f(r.uniforms.u_size, width, height);
    const tanY = Math.tan(camera.fovY / 2);
    gl.uniform2f(r.uniforms.u_tan, tanY * (width / height), tanY);
    gl.uniform3fv(r.uniforms.u_forward, camera.backward.map((v) => -v));
    gl.uniform3fv(r.uniforms.u_right, camera.right);
    gl.uniform3fv(r.uniforms.u_up, camera.up);
    gl.uniform3fv(r.uniforms.u_light, keyLight(camera));
    gl.uniform1i(r.uniforms.u_shading, shading === "normals" ? 1 : 0);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
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
