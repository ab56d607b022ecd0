// The frame view's picture: the newest ray-cast frame from the server, as a texture stretched
// over the viewport. The server renders with the same camera and aspect as the viewport, so
// the stretch only rescales (interactive frames come at a lower resolution).
// Conventions: images arrive as ImageBitmaps, rows from the top; the texture keeps that order
// and the shader flips v.

import { createProgram } from "./gl-program.js";

const VERTEX = `#version 300 es
out vec2 v_uv;
void main() {
  vec2 p = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID & 2) * 2 - 1));
  v_uv = vec2(0.5 * p.x + 0.5, 0.5 - 0.5 * p.y);
  gl_Position = vec4(p, 0.0, 1.0);
}`;

const FRAGMENT = `#version 300 es
precision highp float;
in vec2 v_uv;
uniform sampler2D u_image;
out vec4 outColor;
void main() {
  outColor = vec4(texture(u_image, v_uv).rgb, 1.0);
}`;

export class FrameImage {
  constructor(gl) {
    this.gl = gl;
    this.program = createProgram(gl, VERTEX, FRAGMENT, ["u_image"]);
    this.vao = gl.createVertexArray();
    this.texture = gl.createTexture();
    this.width = 0;
    this.height = 0;
    this.revision = -1;
  }

  get hasImage() {
    return this.width > 0;
  }

  // Uploads an ImageBitmap of the frame that shows `revision`.
  set(bitmap, revision) {
    const gl = this.gl;
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGB8, gl.RGB, gl.UNSIGNED_BYTE, bitmap);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    this.width = bitmap.width;
    this.height = bitmap.height;
    this.revision = revision;
  }

  clear() {
    this.width = this.height = 0;
    this.revision = -1;
  }

  draw() {
    if (!this.hasImage) return;
    const gl = this.gl;
    gl.disable(gl.DEPTH_TEST);
    gl.useProgram(this.program.program);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    gl.uniform1i(this.program.uniforms.u_image, 0);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.bindVertexArray(null);
  }
}
