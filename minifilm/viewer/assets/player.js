// minifilm motion player: skeletons from the page's embedded data, drawn with three.js.
//
// Data (see minifilm/viewer/encode.py): per character the followed root joint's position per
// frame (float32) and every joint's offset from it (int16 * step), all in metres, y up, in the
// axes of the BVH forward kinematics. Each character is drawn inside a THREE.Group moved by its
// lane offset, so a joint mesh's local position is exactly the decoded BVH position.
//
// The three.js pieces (stage, floor, skeletons, labels, orbit camera) are scene.js, and the shaded
// body drawn over each skeleton (on by default; the sticks are a toggle) is mannequin.js, both
// shared with the live demo; html.py inlines them as the import-map entries 'minifilm-scene' and
// 'minifilm-mannequin'.
//
// For tests and scripts the page exposes window.minifilmPlayer (see the end of this file).
import * as THREE from 'three';
import { COLOURS, addFloor, createStage, highlightJoint, layoutLabels, makeLabel, orbitControls, placeCamera,
         poseSkeleton, setSkeletonVisible, skeletonKit } from 'minifilm-scene';
import { mannequinKit, poseMannequin, setMannequinVisible } from 'minifilm-mannequin';

const DATA = JSON.parse(document.getElementById('minifilm-data').textContent);
const SIZE = DATA.size;                      // body size, metres: scales radii, camera, labels

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
const stage = createStage(view, document.getElementById('message'), SIZE);
const { renderer, scene, camera } = stage;

// Floor and grid cover every character's whole path, lanes included.
(function floor() {
  let ext = 2 * SIZE;
  for (const c of CHARS) {
    for (let f = 0; f < c.nFrames; f++) {
      ext = Math.max(ext, Math.abs(c.trailPos[3 * f] + c.offset[0]) + 2 * SIZE,
                     Math.abs(c.trailPos[3 * f + 2] + c.offset[2]) + 2 * SIZE);
    }
  }
  addFloor(scene, SIZE, Math.ceil(2 * ext / DATA.grid) * DATA.grid, DATA.grid);
})();

const kit = skeletonKit(SIZE);
const bodyKit = mannequinKit(SIZE);

const actors = CHARS.map((c, i) => {
  const colour = COLOURS[i % COLOURS.length];
  const group = new THREE.Group();
  group.position.set(c.offset[0], c.offset[1], c.offset[2]);
  scene.add(group);
  const sk = kit.build(group, c.parents, colour);
  const body = bodyKit.build(group, c.parents, colour, c.body);   // c.body: its body plan
  const trailGeometry = new THREE.BufferGeometry();
  const trail = new Float32Array(c.trailPos);
  for (let f = 0; f < c.nFrames; f++) trail[3 * f + 1] += 0.003 * SIZE;  // above the grid
  trailGeometry.setAttribute('position', new THREE.BufferAttribute(trail, 3));
  const trailLine = new THREE.Line(trailGeometry, new THREE.LineBasicMaterial({ color: colour }));
  group.add(trailLine);
  const label = makeLabel(c.name, colour);
  group.add(label);
  return { c, sk, body, group, joints: sk.joints, trailLine, label, frame: -1 };
});

// ---------------------------------------------------------------------------------------------
// Pose update
// ---------------------------------------------------------------------------------------------

const toggles = { body: true, sticks: false, contacts: true, trail: true, labels: true };

function pose(a) {
  const c = a.c, f = charFrame(c);
  a.frame = f;
  const top = poseSkeleton(a.sk, (j, out) => jointPosition(c, f, j, out));
  const touching = [];
  if (toggles.contacts && c.contactVal) {
    const C = c.contactJoints.length;
    for (let k = 0; k < C; k++) {
      if (c.contactVal[f * C + k] >= 128) {  // 0.5 of 255, the GIF's threshold
        highlightJoint(a.sk, c.contactJoints[k]);
        touching.push(c.contactJoints[k]);
      }
    }
  }
  // the sticks and the body are each shown or not; the sticks are always posed (the body reads them)
  setSkeletonVisible(a.sk, toggles.sticks || !toggles.body || !a.body.plan);   // no plan: no body, sticks
  setMannequinVisible(a.body, toggles.body);
  poseMannequin(a.body, a.sk, touching);
  a.trailLine.visible = toggles.trail;
  a.trailLine.geometry.setDrawRange(0, f + 1);
  const root = a.joints[c.rootJoint].position;
  a.label.visible = toggles.labels;
  a.label.position.set(root.x, top + 0.08 * SIZE, root.z);
}

// ---------------------------------------------------------------------------------------------
// Orbit camera (our own: spherical coordinates about a target; follow mode moves the target)
// ---------------------------------------------------------------------------------------------

const orbit = {
  target: new THREE.Vector3(),
  radius: 1,
  azimuth: DATA.heading + 0.6,  // in front of the walkers and to one side
  elevation: 0.28,
};
(function frameAll() {
  const lanes = DATA.lanes || CHARS.length * SIZE;  // metres across every lane, paths included
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

// A pan picks a place: stop following.
orbitControls(renderer.domElement, orbit, camera, SIZE, () => { document.getElementById('follow').value = 'off'; });

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

// Every control gives the focus back after use (a focused checkbox would take Space, a focused
// select the arrows), and the keys are handled for the whole document: they drive the player
// wherever the focus is, except while typing in a text field.
const done = e => e.target.blur();
ui.play.addEventListener('click', e => { setPlaying(!clock.playing); done(e); });
ui.scrub.addEventListener('input', () => { setPlaying(false); setFrame(Number(ui.scrub.value)); });
ui.scrub.addEventListener('change', done);
ui.speed.addEventListener('change', e => { clock.speed = Number(ui.speed.value); done(e); });
ui.follow.addEventListener('change', done);
for (const name of Object.keys(toggles)) {
  document.getElementById(name).addEventListener('change', e => { toggles[name] = e.target.checked; refresh(); done(e); });
}

const TEXT_INPUTS = new Set(['text', 'search', 'number', 'email', 'url', 'password', 'tel']);
function typing(t) {
  return !!t && (t.isContentEditable || t.tagName === 'TEXTAREA' || (t.tagName === 'INPUT' && TEXT_INPUTS.has(t.type)));
}

const KEYS = {
  Space: () => setPlaying(!clock.playing),
  KeyB: () => window.minifilmPlayer.setToggle('body', !toggles.body),
  KeyK: () => window.minifilmPlayer.setToggle('sticks', !toggles.sticks),
  ArrowRight: () => { setPlaying(false); setFrame((globalFrame() + 1) % N_FRAMES); },
  ArrowLeft: () => { setPlaying(false); setFrame((globalFrame() + N_FRAMES - 1) % N_FRAMES); },
};
document.addEventListener('keydown', e => {
  if (!KEYS[e.code] || typing(e.target) || e.ctrlKey || e.metaKey || e.altKey) return;
  // no default action: Space would also toggle a focused checkbox or press a focused button, and
  // the arrows would move a focused slider or select as well as the player
  e.preventDefault();
  if (e.repeat && (e.code === 'KeyB' || e.code === 'KeyK' || e.code === 'Space')) return;
  KEYS[e.code]();
});

const resize = stage.resize;
window.addEventListener('resize', resize);

// ---------------------------------------------------------------------------------------------
// Main loop
// ---------------------------------------------------------------------------------------------

const follow = new THREE.Vector3();
let labelBoxes = [];   // where the names were last drawn (layoutLabels)

function draw(dt) {
  const goal = followPoint(follow);
  // Ease towards the followed point (about 0.15 s) so a switch of mode does not jump.
  if (goal) orbit.target.lerp(goal, dt > 0 ? 1 - Math.exp(-dt / 0.15) : 1);
  placeCamera(camera, orbit);
  // names of characters side by side are stacked so that none covers another (scene.js)
  const el = renderer.domElement;
  labelBoxes = layoutLabels(actors.map(a => a.label), camera, el.clientWidth, el.clientHeight);
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
  // Meshes in the scene now drawn, by kind: {body, sticks} (the mannequin's, the skeletons').
  visibleMeshes: () => ({
    body: actors.reduce((n, a) => n + a.body.all.filter(m => m.visible).length, 0),
    sticks: actors.reduce((n, a) => n + [...a.sk.joints, ...a.sk.bones.map(b => b[0])].filter(m => m.visible).length, 0),
  }),
  setFollow(value) { ui.follow.value = String(value); draw(0); },
  // Character i's shaded body as drawn now: its plan, the head sphere's centre (in its group), and
  // the limbs shown as [parent joint, joint, radius] and the balls' radii (metres).
  body: i => {
    const b = actors[i].body;
    return { plan: b.plan, head: b.head.visible ? b.head.position.toArray() : null,
             limbs: b.limbs.filter(l => l.mesh.visible).map(l => [l.p, l.j, l.r]), balls: b.ballRadius };
  },
  // Where each character's name was last drawn: [left, top, right, bottom] px in the canvas
  // (null: names off or behind the camera).
  labelBoxes: () => labelBoxes.map(b => (b ? [...b] : null)),
  // The characters whose name three.js's own ray test finds at canvas px (x, y) (independent of
  // labelBoxes' arithmetic, to check it).
  labelsAt(x, y) {
    const el = renderer.domElement, ray = new THREE.Raycaster();
    ray.setFromCamera(new THREE.Vector2(2 * x / el.clientWidth - 1, 1 - 2 * y / el.clientHeight), camera);
    return actors.map((a, i) => (a.label.visible && ray.intersectObject(a.label, false).length ? i : -1)).filter(i => i >= 0);
  },
};

resize();
refresh();
orbit.target.copy(followPoint(follow) || new THREE.Vector3(0, 0.5 * SIZE, 0));
draw(0);
window.minifilmPlayer.readyMs = performance.now();  // ms from the start of navigation to ready
window.minifilmPlayer.ready = true;
requestAnimationFrame(tick);
