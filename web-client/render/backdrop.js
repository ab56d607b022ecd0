// The background behind the splats: the server's vertical gradient (server/engine/raycast.cpp,
// Background), so that switching between the splat and the frame view changes nothing but
// the model's own pixels.

import { createProgram } from "./gl-program.js";

const VERTEX = `#version 300 es
out float v_along;
void main() {
  vec2 p = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID & 2) * 2 - 1));
  v_along = 0.5 - 0.5 * p.y; // 0 at the top of the viewport, 1 at the bottom
  gl_Position = vec4(p, 1.0, 1.0);
}`;

const FRAGMENT = `#version 300 es
precision highp float;
in float v_along;
out vec4 outColor;
const vec3 TOP = vec3(0.070, 0.078, 0.095);
const vec3 BOTTOM = vec3(0.018, 0.020, 0.024);
vec3 toSrgb(vec3 c) {
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}
void main() {
  outColor = vec4(toSrgb(mix(TOP, BOTTOM, clamp(v_along, 0.0, 1.0))), 1.0);
}`;

export class Backdrop {
  constructor(gl) {
    this.gl = gl;
    this.program = createProgram(gl, VERTEX, FRAGMENT, []);
    this.vao = gl.createVertexArray();
  }

  draw() {
    const gl = this.gl;
    gl.disable(gl.DEPTH_TEST);
    gl.depthMask(false);
    gl.useProgram(this.program.program);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.bindVertexArray(null);
    gl.depthMask(true);
  }
}
