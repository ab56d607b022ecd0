// The brush cursor: a ring on the surface where the brush would act, as wide as the brush
// radius, turned to lie in the surface's tangent plane, and a dot at its centre; mirrored
// images of the dab (symmetry) get fainter rings. Drawn over everything so it is never hidden.
// Conventions: centres and radii in vu; ring line width in vu, computed by the caller from the
// pixel size at the hit so the line stays about LINE_PIXELS wide on screen.

import { createProgram } from "./gl-program.js";

const SEGMENTS = 96;

const VERTEX = `#version 300 es
layout(location = 0) in vec3 a_ring; // cos, sin, 0 inner / 1 outer edge
uniform mat4 u_viewProjection;
uniform vec3 u_center;
uniform vec3 u_normal;
uniform float u_radius;
uniform float u_width;
void main() {
  vec3 n = normalize(u_normal);
  vec3 helper = abs(n.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
  vec3 t = normalize(cross(helper, n));
  vec3 b = cross(n, t);
  float r = max(0.0, u_radius + (a_ring.z - 0.5) * u_width);
  gl_Position = u_viewProjection * vec4(u_center + r * (a_ring.x * t + a_ring.y * b), 1.0);
}`;

const FRAGMENT = `#version 300 es
precision mediump float;
uniform vec4 u_color;
out vec4 outColor;
void main() {
  outColor = u_color;
}`;

export const LINE_PIXELS = 2;

export class BrushCursor {
  constructor(gl) {
    this.gl = gl;
    this.program = createProgram(gl, VERTEX, FRAGMENT, ["u_viewProjection", "u_center", "u_normal", "u_radius", "u_width", "u_color"]);
    const ring = new Float32Array((SEGMENTS + 1) * 6);
    for (let i = 0; i <= SEGMENTS; ++i) {
      const a = (2 * Math.PI * i) / SEGMENTS;
      ring.set([Math.cos(a), Math.sin(a), 0, Math.cos(a), Math.sin(a), 1], 6 * i);
    }
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, ring, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
  }

  // rings: [{center, normal, radius, width, primary}].
  draw(camera, rings) {
    if (!rings.length) return;
    const gl = this.gl;
    const { program, uniforms } = this.program;
    gl.useProgram(program);
    gl.bindVertexArray(this.vao);
    gl.disable(gl.DEPTH_TEST);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
    gl.uniformMatrix4fv(uniforms.u_viewProjection, false, camera.viewProjection);
    for (const ring of rings) {
      gl.uniform3fv(uniforms.u_center, ring.center);
      gl.uniform3fv(uniforms.u_normal, ring.normal);
      gl.uniform4fv(uniforms.u_color, ring.primary ? [1, 1, 1, 0.9] : [0.6, 0.8, 1, 0.55]);
      gl.uniform1f(uniforms.u_radius, ring.radius);
      gl.uniform1f(uniforms.u_width, ring.width);
      gl.drawArrays(gl.TRIANGLE_STRIP, 0, 2 * (SEGMENTS + 1));
      gl.uniform1f(uniforms.u_radius, ring.width);
      gl.uniform1f(uniforms.u_width, 2 * ring.width);
      gl.drawArrays(gl.TRIANGLE_STRIP, 0, 2 * (SEGMENTS + 1));
    }
    gl.disable(gl.BLEND);
    gl.bindVertexArray(null);
  }
}
