// The brush cursor: rings (a circle of a centre, normal and radius, e.g. the brush's ring in the
// surface's tangent plane, with a dot at its centre for the primary one) and straight segments
// (the edges of a CSG tool's ghost shape), in the tool's colour; mirrored images of the dab
// (symmetry) and inner rings are fainter. Drawn over everything so it is never hidden. The
// geometry comes from math/brush-ghost.js by way of ui/sculpt.js.
// Conventions: centres and radii in vu; ring line width in vu, computed by the caller from the
// pixel size at the hit so the line stays about LINE_PIXELS wide on screen; colours RGB 0..1.

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

const LINE_VERTEX = `#version 300 es
layout(location = 0) in vec3 a_position;
uniform mat4 u_viewProjection;
void main() {
  gl_Position = u_viewProjection * vec4(a_position, 1.0);
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
    this.lines = createProgram(gl, LINE_VERTEX, FRAGMENT, ["u_viewProjection", "u_color"]);
    this.lineVao = gl.createVertexArray();
    gl.bindVertexArray(this.lineVao);
    this.lineBuffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.lineBuffer);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
    this.lineData = new Float32Array(0);
  }

  // cursor: {rings: [{center, normal, radius, width, color, alpha, primary}], segments: [[a, b]],
  // color, alpha?}: the segments are drawn as 1-pixel lines in `color` (opacity `alpha`, 0.9
  // when left out).
  draw(camera, { rings, segments, color, alpha = 0.9 }) {
    if (!rings.length && !segments.length) return;
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
      gl.uniform4fv(uniforms.u_color, [...ring.color, ring.alpha]);
      gl.uniform1f(uniforms.u_radius, ring.radius);
      gl.uniform1f(uniforms.u_width, ring.width);
      gl.drawArrays(gl.TRIANGLE_STRIP, 0, 2 * (SEGMENTS + 1));
      if (!ring.primary) continue;
      gl.uniform1f(uniforms.u_radius, ring.width);
      gl.uniform1f(uniforms.u_width, 2 * ring.width);
      gl.drawArrays(gl.TRIANGLE_STRIP, 0, 2 * (SEGMENTS + 1));
    }
    if (segments.length) {
      const n = segments.length * 6;
      if (this.lineData.length < n) this.lineData = new Float32Array(n);
      segments.forEach(([a, b], i) => this.lineData.set([...a, ...b], 6 * i));
      gl.useProgram(this.lines.program);
      gl.bindVertexArray(this.lineVao);
      gl.bindBuffer(gl.ARRAY_BUFFER, this.lineBuffer);
      gl.bufferData(gl.ARRAY_BUFFER, this.lineData.subarray(0, n), gl.DYNAMIC_DRAW);
      gl.uniformMatrix4fv(this.lines.uniforms.u_viewProjection, false, camera.viewProjection);
      gl.uniform4fv(this.lines.uniforms.u_color, [...color, alpha]);
      gl.drawArrays(gl.LINES, 0, 2 * segments.length);
    }
    gl.disable(gl.BLEND);
    gl.bindVertexArray(null);
  }
}
