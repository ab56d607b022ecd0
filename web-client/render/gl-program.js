// Compiling and linking WebGL2 programs.
// Conventions: shaders are GLSL ES 3.00 source strings; attribute locations are fixed in the
// source with layout(location = N), so vertex arrays can be set up before linking.

// {program, uniforms: name -> WebGLUniformLocation} of a linked program. Throws an Error that
// quotes the driver's log when a shader does not compile or the program does not link.
export function createProgram(gl, vertexSource, fragmentSource, uniformNames) {
  const vs = compile(gl, gl.VERTEX_SHADER, vertexSource);
  const fs = compile(gl, gl.FRAGMENT_SHADER, fragmentSource);
  const program = gl.createProgram();
  gl.attachShader(program, vs);
  gl.attachShader(program, fs);
  gl.linkProgram(program);
  gl.deleteShader(vs);
  gl.deleteShader(fs);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS) && !gl.isContextLost())
    throw new Error(`WebGL program does not link: ${gl.getProgramInfoLog(program)}`);
  const uniforms = {};
  for (const name of uniformNames) uniforms[name] = gl.getUniformLocation(program, name);
  return { program, uniforms };
}

function compile(gl, type, source) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS) && !gl.isContextLost())
    throw new Error(`WebGL shader does not compile: ${gl.getShaderInfoLog(shader)}`);
  return shader;
}

// How much darker fully masked clay is drawn: its albedo times 1 - this at weight 255, less in
// proportion below (server/engine/raycast.cpp, kMaskDarkening, draws frames the same).
export const MASK_DARKENING = 0.45;

// GLSL of a point's albedo (the splat vertex shader computes it): its sRGB colour in linear
// light, darkened by its mask weight (rgbm: colour and weight, each 0..1).
export const PAINT_GLSL = `
vec3 toLinear(vec3 c) {
  return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(0.04045, c));
}

vec3 paintAlbedo(vec4 rgbm) {
  return toLinear(rgbm.rgb) * (1.0 - ${MASK_DARKENING.toFixed(2)} * rgbm.a);
}
`;

// GLSL shared by the shaders that shade the clay: the server's material
// (server/engine/raycast.cpp, shadeLit) without its ambient occlusion, and sRGB output, so that
// the splat view and the ray-cast frames look alike. The albedo is a point's colour (sRGB bytes
// on the wire, protocol/js/splats.js) in linear light, darkened by its mask (PAINT_GLSL).
export const CLAY_GLSL = `
const vec3 ALBEDO = vec3(0.72, 0.46, 0.33); // the clay colour (221, 181, 155) in linear light
const vec3 KEY = vec3(1.10, 1.03, 0.94);
const vec3 SKY = vec3(0.26, 0.29, 0.36);
const vec3 GROUND = vec3(0.12, 0.09, 0.07);
const float WRAP = 0.2;
const float SPECULAR = 0.10;
const float AMBIENT_OCCLUSION = 0.85; // a constant stand-in for the server's field-based term

vec3 clay(vec3 n, vec3 toEye, vec3 light, vec3 up, vec3 albedo) {
  float diffuse = max(0.0, (dot(n, light) + WRAP) / (1.0 + WRAP));
  float h = 0.5 + 0.5 * dot(n, up);
  float s = pow(max(0.0, dot(n, normalize(light + toEye))), 32.0);
  float spec = dot(n, light) > 0.0 ? SPECULAR * s : 0.0;
  float keyShade = diffuse * (0.55 + 0.45 * AMBIENT_OCCLUSION);
  vec3 fill = mix(GROUND, SKY, h);
  return albedo * (KEY * keyShade + fill * AMBIENT_OCCLUSION) + KEY * spec;
}

vec3 toSrgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}
`;
