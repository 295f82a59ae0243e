/* The page (web/index.html): opens an exported scene with the Schnee probes plugin.
 *
 * Query string: gltf=URL (default ../out/default/gltf/scene.gltf, the main job's output),
 * mode=material|off|object|pixel, linear=1 (no tone mapping, linear sRGB output: frames comparable with
 * schnee-view's EXR), sky=0 (probe 0 = the constant 0.2 radiance, no background: schnee-view --no-sky),
 * direct=0 (no punctual lights: --no-direct), probes=1 (probe view on), width/height (fixed canvas size),
 * ui=0 (no control panel, for screenshots).
 * window.schnee exposes the state and readLinear() (the glTF camera's frame, float RGBA) for the tests.
 */
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { SchneeProbesPlugin } from './schnee-gltf-plugin.js';

const q = new URLSearchParams(location.search);
const gltfUrl = q.get('gltf') || '../out/default/gltf/scene.gltf';
const linear = q.get('linear') === '1';
const fixedW = parseInt(q.get('width') || '0', 10), fixedH = parseInt(q.get('height') || '0', 10);
const errorBox = document.getElementById('error');
const status = document.getElementById('status');
const modeSelect = document.getElementById('mode');
const probeViewBox = document.getElementById('probeView');
const gltfCameraBox = document.getElementById('gltfCamera');

if (q.get('ui') === '0') document.getElementById('panel').style.display = 'none';

const state = { ready: false, error: null, probes: null, timing: null };
let readyResolve;
window.schnee = { state, ready: new Promise((r) => { readyResolve = r; }) };

function showError(err) {
  const msg = err && err.message ? err.message : String(err);
  state.error = { name: err && err.name, code: err && err.code, message: msg };
  errorBox.textContent = (err && err.name === 'ShprobeError' ? 'Malformed probe file: ' : 'Could not load the scene: ') + msg;
  errorBox.classList.add('visible');
  status.textContent = 'error';
  readyResolve(state);
}

const renderer = new THREE.WebGLRenderer({ antialias: !linear, preserveDrawingBuffer: true, alpha: true });
renderer.setPixelRatio(fixedW ? 1 : window.devicePixelRatio);
if (linear) {
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
} else {
  renderer.toneMapping = THREE.NeutralToneMapping; /* schnee-view's default: Khronos PBR Neutral */
  renderer.outputColorSpace = THREE.SRGBColorSpace;
}
renderer.setClearColor(0x000000, 0);
const view = document.getElementById('view');
view.appendChild(renderer.domElement);

const scene = new THREE.Scene();
const orbitCamera = new THREE.PerspectiveCamera(50, 16 / 9, 0.05, 1000);
const controls = new OrbitControls(orbitCamera, renderer.domElement);
let gltfCamera = null, probeView = null, probes = null;

function size() {
  const w = fixedW || view.clientWidth, h = fixedH || view.clientHeight;
  renderer.setSize(w, h);
  for (const c of [orbitCamera, gltfCamera]) if (c) { c.aspect = w / h; c.updateProjectionMatrix(); }
}
window.addEventListener('resize', size);

function activeCamera() {
  return gltfCameraBox.checked && gltfCamera ? gltfCamera : orbitCamera;
}

function render() {
  renderer.render(scene, activeCamera());
}

/** The glTF camera's frame as linear float RGBA (row 0 at the bottom), base64 of a Float32Array. */
window.schnee.readLinear = (w, h) => {
  const rt = new THREE.WebGLRenderTarget(w, h, { type: THREE.FloatType, depthBuffer: true });
  const cam = gltfCamera || orbitCamera;
  const aspect = cam.aspect;
  cam.aspect = w / h;
  cam.updateProjectionMatrix();
  const hidden = probeView && probeView.visible;
  if (probeView) probeView.visible = false;
  renderer.setRenderTarget(rt);
  renderer.setClearColor(0x000000, 0);
  renderer.clear();
  renderer.render(scene, cam);
  const px = new Float32Array(4 * w * h);
  renderer.readRenderTargetPixels(rt, 0, 0, w, h, px);
  renderer.setRenderTarget(null);
  rt.dispose();
  if (probeView) probeView.visible = hidden;
  cam.aspect = aspect;
  cam.updateProjectionMatrix();
  const bytes = new Uint8Array(px.buffer);
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(s);
};

window.schnee.setMode = (m) => { modeSelect.value = m; if (probes) probes.setMode(m); render(); };

async function main() {
  const loader = new GLTFLoader();
  loader.register((parser) => new SchneeProbesPlugin(parser, {
    mode: q.get('mode') || 'material', sky: q.get('sky') !== '0', direct: q.get('direct') !== '0', renderer,
  }));
  const t0 = performance.now();
  const gltf = await loader.loadAsync(gltfUrl);
  probes = gltf.userData.schneeProbes;
  scene.add(gltf.scene);
  state.probes = probes;
  state.timing = { ...probes.timing, sceneMs: performance.now() - t0 };
  modeSelect.value = probes.mode;

  /* Background: the sky image is not loaded (EXR); the clear colour stays. */
  if (gltf.cameras && gltf.cameras.length) gltfCamera = gltf.cameras[0];
  else gltfCameraBox.checked = false;
  const box = new THREE.Box3().setFromObject(gltf.scene);
  const c = box.getCenter(new THREE.Vector3());
  if (gltfCamera) {
    gltfCamera.updateMatrixWorld(true);
    orbitCamera.position.copy(gltfCamera.getWorldPosition(new THREE.Vector3()));
    orbitCamera.quaternion.copy(gltfCamera.getWorldQuaternion(new THREE.Quaternion()));
    const dir = new THREE.Vector3(0, 0, -1).applyQuaternion(orbitCamera.quaternion);
    controls.target.copy(orbitCamera.position).addScaledVector(dir, Math.max(1, orbitCamera.position.distanceTo(c)));
  } else {
    controls.target.copy(c);
    orbitCamera.position.copy(c).add(new THREE.Vector3(0, 0.3, 1).multiplyScalar(box.getSize(new THREE.Vector3()).length()));
  }
  controls.update();
  controls.addEventListener('change', () => { if (!gltfCameraBox.checked) render(); });
  controls.addEventListener('start', () => { gltfCameraBox.checked = false; });

  probeView = probes.probeView();
  probeView.visible = q.get('probes') === '1';
  probeViewBox.checked = probeView.visible;
  scene.add(probeView);

  modeSelect.addEventListener('change', () => { probes.setMode(modeSelect.value); render(); });
  probeViewBox.addEventListener('change', () => { probeView.visible = probeViewBox.checked; render(); });
  gltfCameraBox.addEventListener('change', render);

  size();
  render();
  const n = probes.grids.reduce((a, g) => a + g.file.probeCount, 0);
  status.textContent = `${probes.grids.length} grid(s), ${n} probes; probes loaded in ${probes.timing.loadMs.toFixed(1)} ms, ` +
    `queried in ${(probes.timing.totalMs - probes.timing.loadMs).toFixed(1)} ms`;
  state.ready = true;
  renderer.setAnimationLoop(() => { controls.update(); render(); });
  readyResolve(state);
}

main().catch(showError);
