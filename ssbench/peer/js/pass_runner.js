// ssbench peer runner: one three.js shader pass on float textures, read back as floats. Data only in, data out:
// the page's <script id="spec"> holds the textures (base64 float32 RGBA, rows bottom-up as GL stores them), the
// uniforms, the defines and the source patches; the result (base64 float32 RGBA) is written into <pre id="out">.
import * as THREE from 'three';
import { FullScreenQuad } from 'three/addons/postprocessing/Pass.js';

const out = document.getElementById('out');

function floats(b64) {
  const bin = atob(b64);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return new Float32Array(bytes.buffer);
}

function base64(f32) {
  const bytes = new Uint8Array(f32.buffer);
  let bin = '';
  for (let i = 0; i < bytes.length; i += 0x8000) bin += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(bin);
}

function uniformValue(u) {
  switch (u.kind) {
    case 'float': return u.value;
    case 'vec2': return new THREE.Vector2(u.value[0], u.value[1]);
    case 'mat4': return new THREE.Matrix4().fromArray(u.value);          // column-major, as GLSL
    case 'vec3[]': return u.value.map((a) => new THREE.Vector3(a[0], a[1], a[2]));
    default: throw new Error('unknown uniform kind ' + u.kind);
  }
}

function render(Shader) {
  const spec = JSON.parse(document.getElementById('spec').textContent);
  if (!Shader) throw new Error(spec.export + ' not exported by ' + spec.module);
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  if (!renderer.capabilities.isWebGL2) throw new Error('no WebGL2');
  let shaderError = null;
  renderer.debug.onShaderError = (gl, program, vs, fs) => {
    shaderError = 'shader did not compile: ' + gl.getProgramInfoLog(program) + ' ' + gl.getShaderInfoLog(fs);
  };
  if (!renderer.getContext().getExtension('EXT_color_buffer_float')) throw new Error('no EXT_color_buffer_float');
  const uniforms = THREE.UniformsUtils.clone(Shader.uniforms);
  for (const [name, t] of Object.entries(spec.textures)) {
    const tex = new THREE.DataTexture(floats(t.data), t.width, t.height, THREE.RGBAFormat, THREE.FloatType);
    tex.minFilter = THREE.NearestFilter;
    tex.magFilter = THREE.NearestFilter;
    tex.generateMipmaps = false;
    if (t.repeat) { tex.wrapS = THREE.RepeatWrapping; tex.wrapT = THREE.RepeatWrapping; }
    tex.needsUpdate = true;
    uniforms[name] = { value: tex };
  }
  for (const [name, u] of Object.entries(spec.uniforms)) uniforms[name] = { value: uniformValue(u) };
  let fragment = Shader.fragmentShader;
  for (const [from, to] of spec.patches) {
    if (!fragment.includes(from)) throw new Error('patch target not in the shader: ' + from);
    fragment = fragment.split(from).join(to);
  }
  const material = new THREE.ShaderMaterial({
    name: Shader.name, defines: Object.assign({}, Shader.defines, spec.defines), uniforms,
    vertexShader: Shader.vertexShader, fragmentShader: fragment,
    blending: THREE.NoBlending, depthTest: false, depthWrite: false,
  });
  const target = new THREE.WebGLRenderTarget(spec.width, spec.height, {
    type: THREE.FloatType, format: THREE.RGBAFormat, minFilter: THREE.NearestFilter,
    magFilter: THREE.NearestFilter, depthBuffer: false,
  });
  const quad = new FullScreenQuad(material);
  renderer.setRenderTarget(target);
  renderer.setClearColor(0x000000, 0);
  renderer.clear();
  quad.render(renderer);
  if (shaderError) throw new Error(shaderError);
  const pixels = new Float32Array(spec.width * spec.height * 4);
  renderer.readRenderTargetPixels(target, 0, 0, spec.width, spec.height, pixels);
  const errors = renderer.getContext().getError();
  out.textContent = 'OK ' + THREE.REVISION + ' ' + errors + ' ' + base64(pixels);
}

// Synchronous from the page's static imports to the result, so the result is in the page before its load event
// (module scripts run before it): what --dump-dom prints is never the placeholder.
export function run(Shader) {
  try {
    render(Shader);
  } catch (e) {
    out.textContent = 'ERR ' + (e && e.stack ? e.stack : e);
  }
}
