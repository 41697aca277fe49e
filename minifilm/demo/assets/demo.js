// minifilm live demo: draws the character the server steps, and sends it what the user holds.
//
// The character's state lives on the server (minifilm/demo/): this page opens one WebSocket at
// /ws, gets a "hello" (skeleton, styles, settings), then a "frame" every 1/60 s, and sends
// "input" whenever what is held changes (keys or gamepad), "style" for the picker and the blend
// triangle, "settings" for the toggles (protocol: minifilm/demo/protocol.py). The drawing is the
// motion player's (scene.js). For tests and scripts the page exposes window.minifilmDemo (see
// the end of this file).
import * as THREE from 'three';
import { COLOURS, addFloor, createStage, highlightJoint, orbitControls, placeCamera, poseSkeleton,
         skeletonKit } from 'minifilm-scene';

const $ = id => document.getElementById(id);
const DEADZONE = 0.15;       // gamepad sticks rest a little off zero
const CHASE_SECONDS = 0.5;   // the camera swings behind the heading over about this long

const demo = {
  ready: false, connected: false, closed: false, hello: null, frame: null, frames: 0,
  refused: null, errors: [], notices: [], latencyMs: null, sent: 0,
};
window.minifilmDemo = demo;

function toast(text, kind) {
  const box = document.createElement('div');
  box.className = kind;
  box.textContent = text;
  $('toasts').appendChild(box);
  setTimeout(() => box.remove(), 6000);
}

function status(text, bad) {
  $('status').textContent = text;
  $('status').className = bad ? 'bad' : '';
}

// ---------------------------------------------------------------------------------------------
// Connection
// ---------------------------------------------------------------------------------------------

const ws = new WebSocket(`ws://${location.host}/ws`);
let seq = 0;
const sentAt = new Map();   // seq -> performance.now() when sent, until a frame acknowledges it

function send(message) {
  if (ws.readyState !== WebSocket.OPEN) return null;
  message.seq = ++seq;
  sentAt.set(message.seq, performance.now());
  ws.send(JSON.stringify(message));
  demo.sent++;
  return message.seq;
}

ws.addEventListener('open', () => { demo.connected = true; status('connected'); });
ws.addEventListener('close', e => {
  demo.connected = false; demo.closed = true;
  if (!demo.refused) status(`disconnected (${e.code}${e.reason ? ': ' + e.reason : ''}): reload to start again`, true);
});
ws.addEventListener('message', e => {
  const m = JSON.parse(e.data);
  if (m.type === 'frame') onFrame(m);
  else if (m.type === 'hello') setup(m);
  else if (m.type === 'error') { demo.errors.push(m); toast('refused: ' + m.message, 'error'); }
  else if (m.type === 'notice') { demo.notices.push(m); toast(m.message, 'notice'); }
  else if (m.type === 'refused') {
    demo.refused = m.message;
    status('no character free', true);
    $('message').hidden = false;
    $('message').textContent = m.message;
  }
});

// ---------------------------------------------------------------------------------------------
// Scene (built on hello, when the skeleton is known)
// ---------------------------------------------------------------------------------------------

let stage = null, actor = null, floor = null, trail = null, arrow = null, SIZE = 1.7;
const orbit = { target: new THREE.Vector3(0, 0.9, 0), radius: 5, azimuth: Math.PI + 0.5, elevation: 0.3 };
const chase = { offset: 0.5, set: Math.PI + 0.5 };   // azimuth offset from behind the heading
const TRAIL = 600;                                    // the root's last 10 s at 60 fps
const trailPoints = [];

function setup(h) {
  demo.hello = h;
  SIZE = h.size || 1.7;
  stage = createStage($('view'), $('message'), SIZE);
  floor = addFloor(stage.scene, SIZE, 60, 0.5);
  const group = new THREE.Group();
  stage.scene.add(group);
  actor = skeletonKit(SIZE).build(group, h.parents, COLOURS[(h.id - 1) % COLOURS.length]);
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * TRAIL), 3));
  trail = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: 0x8890a0 }));
  stage.scene.add(trail);
  arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, 0x2ca02c, 0.15, 0.08);
  stage.scene.add(arrow);
  orbit.radius = 3.2 * SIZE;
  orbitControls(stage.renderer.domElement, orbit, stage.camera, SIZE, () => { $('follow').checked = false; });
  window.addEventListener('resize', stage.resize);
  stage.resize();

  for (const id of ['style', 'corner0', 'corner1', 'corner2']) {
    for (const name of h.styles) $(id).add(new Option(name, name));
  }
  const start = Object.keys(h.style)[0];
  $('style').value = start;
  const others = h.styles.filter(n => n !== start);
  [start, others[0] || start, others[1] || start].forEach((n, i) => { $('corner' + i).value = n; });
  $('footLock').checked = h.settings.footLock;
  $('fit').checked = h.settings.fit;
  demo.ready = true;
  requestAnimationFrame(tick);
}

function onFrame(f) {
  demo.frame = f;
  demo.frames++;
  if (f.ack !== null && sentAt.size) {
    for (const [s, at] of sentAt) {
      if (s <= f.ack) {
        // the first frame made with this message: the time from input to motion
        if (s === f.ack) demo.latencyMs = performance.now() - at;
        sentAt.delete(s);
      }
    }
  }
  frameTimes.push(f.frameMs);
  if (frameTimes.length > 60) frameTimes.shift();
  arrivals.push(performance.now());
  if (arrivals.length > 61) arrivals.shift();
  trailPoints.push(f.root[0], 0.003 * SIZE, f.root[1]);
  if (trailPoints.length > 3 * TRAIL) trailPoints.splice(0, 3);
  fresh = true;
}

let fresh = false;
const frameTimes = [], arrivals = [];

function pose() {
  const f = demo.frame, p = f.positions;
  poseSkeleton(actor, (j, out) => out.set(p[3 * j], p[3 * j + 1], p[3 * j + 2]));
  const toes = demo.hello.contactJoints;
  toes.forEach((j, k) => { if (f.contacts[k] >= 0.5) highlightJoint(actor, j); });
  const a = trail.geometry.attributes.position;
  a.array.set(trailPoints);
  a.needsUpdate = true;
  trail.geometry.setDrawRange(0, trailPoints.length / 3);
  const v = f.velocity, speed = Math.hypot(v[0], v[1]);
  arrow.visible = speed > 1e-3;
  if (arrow.visible) {
    arrow.position.set(f.root[0], 0.01 * SIZE, f.root[1]);
    arrow.setDirection(new THREE.Vector3(v[0] / speed, 0, v[1] / speed));
    arrow.setLength(0.25 + 0.35 * speed, 0.15, 0.08);
  }
}

// ---------------------------------------------------------------------------------------------
// Read-outs: speeds, frame time, the style mix, four local-phase dials (the paper's Figure 4)
// ---------------------------------------------------------------------------------------------

const median = xs => { const s = [...xs].sort((a, b) => a - b); return s.length ? s[s.length >> 1] : NaN; };
const phaseScale = [1e-3, 1e-3, 1e-3, 1e-3];

function readouts() {
  const f = demo.frame;
  $('commanded').textContent = `${f.commanded.toFixed(2)} m/s`;
  $('actual').textContent = `${f.speed.toFixed(2)} m/s`;
  $('frametime').textContent = `${median(frameTimes).toFixed(2)} ms`;   // median of the last 60
  const span = (arrivals[arrivals.length - 1] - arrivals[0]) / 1000;
  $('fps').textContent = arrivals.length > 1 ? `${((arrivals.length - 1) / span).toFixed(1)} / s` : '-';
  $('latency').textContent = demo.latencyMs === null ? '-' : `${demo.latencyMs.toFixed(0)} ms`;
  const mix = Object.entries(f.weights).sort((a, b) => b[1] - a[1]).map(([n, w]) => `${n} ${w.toFixed(2)}`);
  const target = Object.keys(f.target).join(' + ');
  $('mix').textContent = `now ${mix.join(' · ')}` + (mix.length > 1 || !(target in f.weights) ? ` → ${target}` : '') +
    (f.calibrated ? '' : ' (speed calibration on its way)');
  for (let k = 0; k < 4; k++) dial(k, f.phases[2 * k], f.phases[2 * k + 1]);
}

// A hand at the phase angle (2 pi phase clockwise from the top), as long as the amplitude
// relative to the largest seen lately on that limb.
function dial(k, s, c) {
  const canvas = $('phase' + k), g = canvas.getContext('2d'), r = canvas.width / 2 - 4;
  const amplitude = Math.hypot(s, c);
  phaseScale[k] = Math.max(amplitude, phaseScale[k] * 0.995);
  const length = r * Math.min(1, amplitude / phaseScale[k]);
  g.clearRect(0, 0, canvas.width, canvas.height);
  g.save();
  g.translate(canvas.width / 2, canvas.height / 2);
  g.strokeStyle = '#b9bec8'; g.lineWidth = 2;
  g.beginPath(); g.arc(0, 0, r, 0, 2 * Math.PI); g.stroke();
  const angle = Math.atan2(s, c);
  g.strokeStyle = COLOURS_CSS[k]; g.lineWidth = 3;
  g.beginPath(); g.moveTo(0, 0); g.lineTo(length * Math.sin(angle), -length * Math.cos(angle)); g.stroke();
  g.restore();
}
const COLOURS_CSS = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd'];

// ---------------------------------------------------------------------------------------------
// Input: keys and gamepad -> {move: [right, forward], turn, speed}, sent when it changes
// ---------------------------------------------------------------------------------------------

const held = new Set();
const KEYS = new Set(['KeyW', 'KeyA', 'KeyS', 'KeyD', 'KeyQ', 'KeyE', 'ArrowUp', 'ArrowDown', 'ArrowLeft',
                      'ArrowRight', 'ShiftLeft', 'ShiftRight']);
let lastInput = '';

function typing(e) {
  const t = e.target;
  return t && (t.tagName === 'SELECT' || (t.tagName === 'INPUT' && t.type === 'text'));
}

window.addEventListener('keydown', e => {
  if (!KEYS.has(e.code) || typing(e)) return;
  e.preventDefault();
  held.add(e.code);
  sendInput();
});
window.addEventListener('keyup', e => {
  if (!KEYS.has(e.code)) return;
  held.delete(e.code);
  sendInput();
});
// A key released while the page had no focus never sends keyup: let go of everything.
window.addEventListener('blur', () => { held.clear(); sendInput(); });
document.addEventListener('visibilitychange', () => { if (document.hidden) { held.clear(); sendInput(); } });

const clamp1 = x => Math.max(-1, Math.min(1, x));
const dead = x => (Math.abs(x) < DEADZONE ? 0 : x);
const q = x => Math.round(x * 50) / 50;   // 0.02 steps: a resting stick does not flood the server

function gamepad() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  for (const pad of pads) {
    if (!pad || !pad.connected) continue;
    const trigger = pad.buttons[7] ? pad.buttons[7].value : 0;
    return { right: dead(pad.axes[0] || 0), forward: -dead(pad.axes[1] || 0), turn: dead(pad.axes[2] || 0),
             speed: trigger < 0.05 ? 0 : trigger };
  }
  return null;
}

function currentInput() {
  const k = code => (held.has(code) ? 1 : 0);
  let right = k('KeyD') + k('ArrowRight') > 0 ? 1 : 0, left = k('KeyA') + k('ArrowLeft') > 0 ? 1 : 0;
  let forward = (k('KeyW') || k('ArrowUp')) - (k('KeyS') || k('ArrowDown'));
  let side = right - left, turn = k('KeyE') - k('KeyQ');
  let speed = k('ShiftLeft') || k('ShiftRight') ? 1 : 0;
  const pad = gamepad();
  if (pad) {
    side = clamp1(side + pad.right); forward = clamp1(forward + pad.forward);
    turn = clamp1(turn + pad.turn); speed = Math.max(speed, pad.speed);
  }
  return { type: 'input', move: [q(side), q(forward)], turn: q(turn), speed: q(speed) };
}

function sendInput() {
  const input = currentInput();
  const key = JSON.stringify(input);
  if (key === lastInput) return;
  if (send(input) !== null) lastInput = key;   // not yet connected: try again next frame
}

// ---------------------------------------------------------------------------------------------
// Style: the picker, the blend triangle (Sec. 4.4, barycentric weights), the toggles
// ---------------------------------------------------------------------------------------------

const transition = () => Number($('transition').value);
$('transition').addEventListener('input', () => { $('transition-value').textContent = `${transition().toFixed(1)} s`; });

function setStyle(name) {
  $('style').value = name;
  return send({ type: 'style', weights: { [name]: 1 }, seconds: transition() });
}
$('style').addEventListener('change', e => { setStyle(e.target.value); e.target.blur(); });

const tri = $('triangle');
const corners = () => {
  const w = tri.width, h = tri.height, m = 14;
  return [[w / 2, m], [m, h - m], [w - m, h - m]];   // top, bottom left, bottom right
};
let dot = [1, 0, 0];

function barycentric(x, y) {
  const [[x0, y0], [x1, y1], [x2, y2]] = corners();
  const d = (y1 - y2) * (x0 - x2) + (x2 - x1) * (y0 - y2);
  let a = ((y1 - y2) * (x - x2) + (x2 - x1) * (y - y2)) / d;
  let b = ((y2 - y0) * (x - x2) + (x0 - x2) * (y - y2)) / d;
  let c = 1 - a - b;
  [a, b, c] = [a, b, c].map(v => Math.max(0, v));      // outside: onto the nearest edge
  const s = a + b + c;
  [a, b, c] = [a / s, b / s, c / s];
  // near a corner (within 0.06 of its weight): exactly that style
  for (let i = 0; i < 3; i++) if ([a, b, c][i] > 0.94) return [0, 1, 2].map(j => (j === i ? 1 : 0));
  return [a, b, c];
}

function drawTriangle() {
  const g = tri.getContext('2d'), P = corners();
  g.clearRect(0, 0, tri.width, tri.height);
  g.fillStyle = '#eef0f4'; g.strokeStyle = '#9aa1ad'; g.lineWidth = 1.5;
  g.beginPath(); g.moveTo(...P[0]); g.lineTo(...P[1]); g.lineTo(...P[2]); g.closePath(); g.fill(); g.stroke();
  P.forEach((p, i) => { g.fillStyle = COLOURS_CSS[i]; g.beginPath(); g.arc(p[0], p[1], 5, 0, 2 * Math.PI); g.fill(); });
  const x = dot[0] * P[0][0] + dot[1] * P[1][0] + dot[2] * P[2][0];
  const y = dot[0] * P[0][1] + dot[1] * P[1][1] + dot[2] * P[2][1];
  g.fillStyle = '#222'; g.beginPath(); g.arc(x, y, 6, 0, 2 * Math.PI); g.fill();
}

function setBlend(weights) {
  dot = weights.slice();
  drawTriangle();
  const mix = {};
  for (let i = 0; i < 3; i++) {
    const name = $('corner' + i).value;
    if (weights[i] > 0) mix[name] = (mix[name] || 0) + weights[i];
  }
  return send({ type: 'style', weights: mix, seconds: transition() });
}

let dragging = false, lastBlendSent = 0;
function blendAt(e) {
  const r = tri.getBoundingClientRect();
  const weights = barycentric((e.clientX - r.left) * tri.width / r.width, (e.clientY - r.top) * tri.height / r.height);
  dot = weights;
  drawTriangle();
  const now = performance.now();
  if (e.type !== 'pointermove' || now - lastBlendSent > 50) {   // at most 20 changes a second while dragging
    lastBlendSent = now;
    setBlend(weights);
  }
}
tri.addEventListener('pointerdown', e => { dragging = true; tri.setPointerCapture(e.pointerId); blendAt(e); });
tri.addEventListener('pointermove', e => { if (dragging) blendAt(e); });
tri.addEventListener('pointerup', e => { if (dragging) { dragging = false; blendAt(e); } });
for (let i = 0; i < 3; i++) $('corner' + i).addEventListener('change', e => { setBlend(dot); e.target.blur(); });
drawTriangle();

for (const name of ['footLock', 'fit']) {
  $(name).addEventListener('change', e => { send({ type: 'settings', [name]: e.target.checked }); e.target.blur(); });
}
$('reset').addEventListener('click', e => { send({ type: 'reset' }); trailPoints.length = 0; e.target.blur(); });

// ---------------------------------------------------------------------------------------------
// Main loop: poll the gamepad, pose the newest frame, chase it with the camera, draw
// ---------------------------------------------------------------------------------------------

const angle = a => Math.atan2(Math.sin(a), Math.cos(a));
let last = null, lastReadout = 0;

function tick(now) {
  const dt = last === null ? 0 : Math.min((now - last) / 1000, 0.1);
  last = now;
  sendInput();   // picks up the gamepad; keys are sent as they change
  if (demo.frame && fresh) {
    pose();
    fresh = false;
    if (now - lastReadout > 100) { readouts(); lastReadout = now; }
  }
  if (demo.frame && $('follow').checked) {
    const f = demo.frame, k = dt > 0 ? 1 - Math.exp(-dt / 0.15) : 1;
    orbit.target.lerp(new THREE.Vector3(f.root[0], 0.5 * SIZE, f.root[1]), k);
    // behind the heading, plus whatever the user dragged the camera round by
    chase.offset += angle(orbit.azimuth - chase.set);
    const behind = Math.atan2(f.heading[0], f.heading[1]) + Math.PI + chase.offset;
    orbit.azimuth = chase.set + angle(behind - chase.set) * (dt > 0 ? 1 - Math.exp(-dt / CHASE_SECONDS) : 1);
    chase.set = orbit.azimuth;
  }
  const cell = floor.cell;   // the floor moves under the camera by whole cells: it looks endless
  floor.ground.position.set(Math.round(orbit.target.x / cell) * cell, 0, Math.round(orbit.target.z / cell) * cell);
  floor.grid.position.set(floor.ground.position.x, floor.grid.position.y, floor.ground.position.z);
  placeCamera(stage.camera, orbit);
  stage.renderer.render(stage.scene, stage.camera);
  requestAnimationFrame(tick);
}

// ---------------------------------------------------------------------------------------------
// Public handle for tests and scripts (window.minifilmDemo): ready, connected, hello, frame (the
// newest frame message), frames (how many arrived), errors, notices, refused, latencyMs, and:
// ---------------------------------------------------------------------------------------------

Object.assign(demo, {
  send,                                   // (message object) -> its seq; e.g. send({type: 'reset'})
  setStyle,                               // (name) -> seq: as the picker does
  setBlend,                               // ([w0, w1, w2]) -> seq: the triangle's corners weighted
  setCorners(names) { names.forEach((n, i) => { $('corner' + i).value = n; }); },
  // Client coordinates of a corner of the blend triangle (for a real click on it).
  corner(i) {
    const r = tri.getBoundingClientRect(), p = corners()[i];
    return [r.left + p[0] * r.width / tri.width, r.top + p[1] * r.height / tri.height];
  },
  setToggle(name, on) { $(name).checked = on; $(name).dispatchEvent(new Event('change')); },
  // Joint positions the page shows now ((J, 3), metres, world).
  shownJoints: () => actor.joints.map(m => [m.position.x, m.position.y, m.position.z]),
  // The orbit camera now: azimuth (radians about +y) and the point it looks at.
  camera: () => ({ azimuth: orbit.azimuth, target: orbit.target.toArray() }),
});
