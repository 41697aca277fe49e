// minifilm motion player: skeletons from the page's embedded data, drawn with three.js.
//
// Data (see minifilm/viewer/encode.py): per character the followed root joint's position per
// frame (float32) and every joint's offset from it (int16 * step), all in metres, y up, in the
// axes of the BVH forward kinematics. Each character is drawn inside a THREE.Group moved by its
// lane offset, so a joint mesh's local position is exactly the decoded BVH position.
//
// For tests and scripts the page exposes window.minifilmPlayer (see the end of this file).
import * as THREE from 'three';

const DATA = JSON.parse(document.getElementById('minifilm-data').textContent);
const SIZE = DATA.size;                      // body size, metres: scales radii, camera, labels
const COLOURS = [0x1f77b4, 0xd62728, 0x2ca02c, 0x9467bd, 0xff7f0e, 0x17becf, 0x8c564b, 0xe377c2];
const CONTACT_COLOUR = 0xffc400;
const UP = new THREE.Vector3(0, 1, 0);

// ---------------------------------------------------------------------------------------------
// Decoding
// ---------------------------------------------------------------------------------------------

function bytes(b64) {
  const bin = atob(b64);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

function decode(c) {
  return {
    ...c,
    rootPos: new Float32Array(bytes(c.root).buffer),       // (F, 3)
    relPos: new Int16Array(bytes(c.rel).buffer),           // (F, J, 3)
    trailPos: new Float32Array(bytes(c.trail).buffer),     // (F, 3)
    contactVal: c.contacts ? bytes(c.contacts) : null,     // (F, C), 0..255
  };
}

const CHARS = DATA.characters.map(decode);

// Joint j of character c at frame f, metres (BVH axes): root + rel * step, as in encode.py.
function jointPosition(c, f, j, out) {
  const J = c.nJoints, r = 3 * f, q = 3 * (f * J + j);
  return out.set(c.rootPos[r] + c.relPos[q] * c.step,
                 c.rootPos[r + 1] + c.relPos[q + 1] * c.step,
                 c.rootPos[r + 2] + c.relPos[q + 2] * c.step);
}

// ---------------------------------------------------------------------------------------------
// Timeline: the player clock runs at the highest frame rate; each character shows its frame
// nearest to the clock, floor(t * fps + 0.5), held on its last frame (as timeline.py does).
// ---------------------------------------------------------------------------------------------

const FPS = Math.max(...CHARS.map(c => c.fps));
const N_FRAMES = Math.max(...CHARS.map(c => Math.ceil(c.nFrames / c.fps * FPS - 1e-3)));
const DURATION = N_FRAMES / FPS;
const clock = { t: 0, playing: true, speed: 1 };

const globalFrame = () => Math.min(Math.floor(clock.t * FPS + 1e-6), N_FRAMES - 1);
const charFrame = c => Math.min(Math.floor(globalFrame() / FPS * c.fps + 0.5), c.nFrames - 1);

// ---------------------------------------------------------------------------------------------
// Scene
// ---------------------------------------------------------------------------------------------

const view = document.getElementById('view');
let renderer;
try {
  renderer = new THREE.WebGLRenderer({ antialias: true });
} catch (e) {
  // Say so on the page rather than leaving it blank (old browser, or WebGL switched off).
  const box = document.getElementById('message');
  box.hidden = false;
  box.textContent = 'This player needs WebGL, which this browser does not provide: ' + e.message;
  throw e;
}
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.setSize(view.clientWidth, view.clientHeight);
view.appendChild(renderer.domElement);

const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f5f7);
scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f99, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(0.5, 1.0, 0.8);
scene.add(sun);

// Floor and grid cover every character's whole path, lanes included.
(function floor() {
  let ext = 2 * SIZE;
  for (const c of CHARS) {
    for (let f = 0; f < c.nFrames; f++) {
      ext = Math.max(ext, Math.abs(c.trailPos[3 * f] + c.offset[0]) + 2 * SIZE,
                     Math.abs(c.trailPos[3 * f + 2] + c.offset[2]) + 2 * SIZE);
    }
  }
  const cells = Math.min(2000, Math.ceil(2 * ext / DATA.grid));
  const span = cells * DATA.grid;
  const ground = new THREE.Mesh(new THREE.PlaneGeometry(span, span),
                                new THREE.MeshLambertMaterial({ color: 0xe6e8ec }));
  ground.rotation.x = -Math.PI / 2;
  scene.add(ground);
  const grid = new THREE.GridHelper(span, cells, 0xb9bec8, 0xcdd1d8);
  grid.position.y = 0.001 * SIZE;  // just above the floor, so it does not flicker into it
  scene.add(grid);
})();

const jointGeometry = new THREE.SphereGeometry(0.022 * SIZE, 12, 8);
const boneGeometry = new THREE.CylinderGeometry(0.013 * SIZE, 0.013 * SIZE, 1, 8);
boneGeometry.translate(0, 0.5, 0);  // spans y in [0, 1]: scaled to the bone length, from the parent
const contactMaterial = new THREE.MeshLambertMaterial({ color: CONTACT_COLOUR });

// Name labels keep a constant size on screen (sizeAttenuation off: scale is a fraction of the
// view height), so they stay readable however far the camera zooms out.
function makeLabel(text, colour) {
  const canvas = document.createElement('canvas');
  const g = canvas.getContext('2d');
  const font = 'bold 44px system-ui, sans-serif';
  g.font = font;
  canvas.width = Math.ceil(g.measureText(text).width) + 24;
  canvas.height = 64;
  g.font = font;  // resizing the canvas resets its state
  g.textAlign = 'center'; g.textBaseline = 'middle';
  g.lineWidth = 8; g.strokeStyle = 'rgba(255,255,255,0.92)';
  g.strokeText(text, canvas.width / 2, 32);
  g.fillStyle = '#' + colour.toString(16).padStart(6, '0');
  g.fillText(text, canvas.width / 2, 32);
  const texture = new THREE.CanvasTexture(canvas);
  texture.colorSpace = THREE.SRGBColorSpace;  // the canvas holds sRGB colours
  const sprite = new THREE.Sprite(new THREE.SpriteMaterial({
    map: texture, depthTest: false, transparent: true, sizeAttenuation: false }));
  const height = 0.032;
  sprite.scale.set(height * canvas.width / canvas.height, height, 1);
  sprite.center.set(0.5, 0);  // anchored at its bottom edge, just above the head
  sprite.renderOrder = 10;    // drawn last, over the skeletons
  return sprite;
}

const actors = CHARS.map((c, i) => {
  const colour = COLOURS[i % COLOURS.length];
  const material = new THREE.MeshLambertMaterial({ color: colour });
  const group = new THREE.Group();
  group.position.set(c.offset[0], c.offset[1], c.offset[2]);
  scene.add(group);
  const joints = [], bones = [];
  for (let j = 0; j < c.nJoints; j++) {
    const m = new THREE.Mesh(jointGeometry, material);
    group.add(m); joints.push(m);
    if (c.parents[j] >= 0) {
      const b = new THREE.Mesh(boneGeometry, material);
      group.add(b); bones.push([b, j, c.parents[j]]);
    }
  }
  const trailGeometry = new THREE.BufferGeometry();
  const trail = new Float32Array(c.trailPos);
  for (let f = 0; f < c.nFrames; f++) trail[3 * f + 1] += 0.003 * SIZE;  // above the grid
  trailGeometry.setAttribute('position', new THREE.BufferAttribute(trail, 3));
  const trailLine = new THREE.Line(trailGeometry, new THREE.LineBasicMaterial({ color: colour }));
  group.add(trailLine);
  const label = makeLabel(c.name, colour);
  group.add(label);
  return { c, material, group, joints, bones, trailLine, label, frame: -1 };
});

// ---------------------------------------------------------------------------------------------
// Pose update
// ---------------------------------------------------------------------------------------------

const toggles = { contacts: true, trail: true, labels: true };
const tmp = new THREE.Vector3();

function pose(a) {
  const c = a.c, f = charFrame(c);
  a.frame = f;
  let top = -Infinity;
  for (let j = 0; j < c.nJoints; j++) {
    jointPosition(c, f, j, a.joints[j].position);
    top = Math.max(top, a.joints[j].position.y);
    a.joints[j].material = a.material;
    a.joints[j].scale.setScalar(1);
  }
  for (const [mesh, j, p] of a.bones) {
    const from = a.joints[p].position;
    tmp.subVectors(a.joints[j].position, from);
    const length = tmp.length();
    mesh.position.copy(from);
    if (length > 1e-9) mesh.quaternion.setFromUnitVectors(UP, tmp.divideScalar(length));
    mesh.scale.set(1, Math.max(length, 1e-9), 1);
  }
  if (toggles.contacts && c.contactVal) {
    const C = c.contactJoints.length;
    for (let k = 0; k < C; k++) {
      if (c.contactVal[f * C + k] >= 128) {  // 0.5 of 255, the GIF's threshold
        const m = a.joints[c.contactJoints[k]];
        m.material = contactMaterial;
        m.scale.setScalar(1.8);
      }
    }
  }
  a.trailLine.visible = toggles.trail;
  a.trailLine.geometry.setDrawRange(0, f + 1);
  const root = a.joints[c.rootJoint].position;
  a.label.visible = toggles.labels;
  a.label.position.set(root.x, top + 0.08 * SIZE, root.z);
}

// ---------------------------------------------------------------------------------------------
// Orbit camera (our own: spherical coordinates about a target; follow mode moves the target)
// ---------------------------------------------------------------------------------------------

const camera = new THREE.PerspectiveCamera(40, 1, 0.01 * SIZE, 2000 * SIZE);
const orbit = {
  target: new THREE.Vector3(),
  radius: 1,
  azimuth: DATA.heading + 0.6,  // in front of the walkers and to one side
  elevation: 0.28,
};
(function frameAll() {
  const lanes = CHARS.length * SIZE;
  orbit.radius = Math.max(3.2 * SIZE, 0.9 * lanes / (2 * Math.tan(THREE.MathUtils.degToRad(20))));
})();

function followPoint(out) {
  const mode = document.getElementById('follow').value;
  const list = mode === 'all' ? actors : (mode === 'off' ? [] : [actors[Number(mode)]]);
  if (!list.length) return null;
  out.set(0, 0, 0);
  for (const a of list) out.add(a.joints[a.c.rootJoint].position).add(a.group.position);
  out.divideScalar(list.length);
  out.y = 0.5 * SIZE;
  return out;
}

function placeCamera() {
  const ce = Math.cos(orbit.elevation);
  camera.position.set(orbit.target.x + orbit.radius * ce * Math.sin(orbit.azimuth),
                      orbit.target.y + orbit.radius * Math.sin(orbit.elevation),
                      orbit.target.z + orbit.radius * ce * Math.cos(orbit.azimuth));
  camera.lookAt(orbit.target);
}

(function orbitControls() {
  const el = renderer.domElement;
  let drag = null;
  el.addEventListener('contextmenu', e => e.preventDefault());
  el.addEventListener('pointerdown', e => {
    drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey };
    el.setPointerCapture(e.pointerId);
  });
  el.addEventListener('pointerup', e => { drag = null; el.releasePointerCapture(e.pointerId); });
  el.addEventListener('pointermove', e => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.pan) {
      document.getElementById('follow').value = 'off';  // a pan picks a place: stop following
      const k = orbit.radius / el.clientHeight;
      const right = new THREE.Vector3().setFromMatrixColumn(camera.matrix, 0);
      const up = new THREE.Vector3().setFromMatrixColumn(camera.matrix, 1);
      orbit.target.addScaledVector(right, -dx * k).addScaledVector(up, dy * k);
    } else {
      orbit.azimuth -= dx * 0.008;
      orbit.elevation = THREE.MathUtils.clamp(orbit.elevation + dy * 0.008, -0.2, 1.5);
    }
  });
  el.addEventListener('wheel', e => {
    e.preventDefault();
    orbit.radius = THREE.MathUtils.clamp(orbit.radius * Math.exp(e.deltaY * 0.001), 0.3 * SIZE, 500 * SIZE);
  }, { passive: false });
})();

// ---------------------------------------------------------------------------------------------
// Controls
// ---------------------------------------------------------------------------------------------

const ui = {
  play: document.getElementById('play'),
  scrub: document.getElementById('scrub'),
  time: document.getElementById('time'),
  speed: document.getElementById('speed'),
  follow: document.getElementById('follow'),
};
ui.scrub.max = String(N_FRAMES - 1);
CHARS.forEach((c, i) => ui.follow.add(new Option(c.name, String(i))));
if (!CHARS.some(c => c.contactVal)) {
  const box = document.getElementById('contacts');
  box.disabled = true;
  box.parentElement.title = 'no foot contacts were given for these motions';
}

function setPlaying(on) {
  clock.playing = on;
  ui.play.innerHTML = on ? '&#10074;&#10074;' : '&#9654;';
}

function refresh() {
  for (const a of actors) pose(a);
  const g = globalFrame();
  ui.scrub.value = String(g);
  ui.time.textContent = `${clock.t.toFixed(2)} s  frame ${g + 1}/${N_FRAMES}`;
}

ui.play.addEventListener('click', () => setPlaying(!clock.playing));
ui.scrub.addEventListener('input', () => { setPlaying(false); setFrame(Number(ui.scrub.value)); });
ui.speed.addEventListener('change', () => { clock.speed = Number(ui.speed.value); });
for (const name of Object.keys(toggles)) {
  document.getElementById(name).addEventListener('change', e => { toggles[name] = e.target.checked; refresh(); });
}
window.addEventListener('keydown', e => {
  if (e.target.tagName === 'SELECT' || (e.target.tagName === 'INPUT' && e.target.type !== 'range')) return;
  if (e.code === 'Space') { e.preventDefault(); setPlaying(!clock.playing); }
  if (e.code === 'ArrowRight' || e.code === 'ArrowLeft') {
    e.preventDefault(); setPlaying(false);
    setFrame((globalFrame() + (e.code === 'ArrowRight' ? 1 : N_FRAMES - 1)) % N_FRAMES);
  }
});

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);

// ---------------------------------------------------------------------------------------------
// Main loop
// ---------------------------------------------------------------------------------------------

const follow = new THREE.Vector3();

function draw(dt) {
  const goal = followPoint(follow);
  // Ease towards the followed point (about 0.15 s) so a switch of mode does not jump.
  if (goal) orbit.target.lerp(goal, dt > 0 ? 1 - Math.exp(-dt / 0.15) : 1);
  placeCamera();
  renderer.render(scene, camera);
}

function setFrame(i) {
  const g = Math.max(0, Math.min(N_FRAMES - 1, Math.round(Number(i)) || 0));
  clock.t = g / FPS;
  refresh();
  draw(0);
  return g;
}

let last = null;
function tick(now) {
  const dt = last === null ? 0 : Math.min((now - last) / 1000, 0.1);
  last = now;
  if (clock.playing && dt > 0) {
    const before = globalFrame();
    clock.t = (clock.t + dt * clock.speed) % DURATION;
    if (globalFrame() !== before) refresh();
  }
  draw(dt);
  requestAnimationFrame(tick);
}

// ---------------------------------------------------------------------------------------------
// Public handle for tests and scripts
// ---------------------------------------------------------------------------------------------

window.minifilmPlayer = {
  ready: false,
  nFrames: N_FRAMES,                   // player frames (at the highest character frame rate)
  fps: FPS,
  duration: DURATION,
  get frame() { return globalFrame(); },
  get time() { return clock.t; },
  get playing() { return clock.playing; },
  play() { setPlaying(true); },
  pause() { setPlaying(false); },
  setFrame,                            // (i) -> the frame set; poses and draws at once
  characters: CHARS.map(c => ({ name: c.name, nFrames: c.nFrames, fps: c.fps, nJoints: c.nJoints,
                                parents: c.parents, jointNames: c.jointNames, offset: c.offset,
                                step: c.step })),
  characterFrame: i => actors[i].frame,  // the frame of character i now shown
  // Joint positions character i shows now, metres in BVH axes ((J, 3) array): the positions of
  // its joint meshes inside its group, i.e. without the lane offset.
  shownJoints: i => actors[i].joints.map(m => [m.position.x, m.position.y, m.position.z]),
  // The same in the scene's world coordinates (lane offset included).
  shownWorldJoints: i => actors[i].joints.map(m => m.getWorldPosition(new THREE.Vector3()).toArray()),
  setToggle(name, on) { document.getElementById(name).checked = on; toggles[name] = on; refresh(); draw(0); },
  setFollow(value) { ui.follow.value = String(value); draw(0); },
};

resize();
refresh();
orbit.target.copy(followPoint(follow) || new THREE.Vector3(0, 0.5 * SIZE, 0));
draw(0);
window.minifilmPlayer.readyMs = performance.now();  // ms from the start of navigation to ready
window.minifilmPlayer.ready = true;
requestAnimationFrame(tick);
