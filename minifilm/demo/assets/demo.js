// minifilm live demo: draws the character the server steps, and sends it what the user holds.
//
// The character's state lives on the server (minifilm/demo/): this page opens one WebSocket at
// /ws, gets a "hello" (skeleton, styles, settings), then a "frame" every 1/60 s, and sends
// "input" whenever what is held changes (keys or gamepad), "style" for the picker and the blend
// triangle, "settings" for the toggles, "record" for the record button (answered with
// "recording" (BVH text, which the page downloads) and "recordingGif" (a GIF to save, or why not); protocol:
// minifilm/demo/protocol.py and record.py). The drawing is the motion player's: scene.js (stage,
// floor, sticks, labels) and mannequin.js (the shaded body, on by default), plus the path ahead
// (the network's predicted trajectory and where the held keys lead; T). For tests and scripts
// the page exposes window.minifilmDemo (see the end of this file).
//
// What the page shows is only what it has: read-outs say "—" until their first value, the
// input -> motion time is measured only for the user's own input messages, and frames received is
// the number that arrived in the last second.
import * as THREE from 'three';
import { COLOURS, addFloor, createStage, highlightJoint, makeLabel, orbitControls, placeCamera, poseSkeleton,
         setSkeletonVisible, skeletonKit } from 'minifilm-scene';
import { mannequinKit, poseMannequin, setMannequinVisible } from 'minifilm-mannequin';

const $ = id => document.getElementById(id);
const DEADZONE = 0.15;       // gamepad sticks rest a little off zero
const CHASE_SECONDS = 0.5;   // the camera swings behind the body's facing over about this long
// One colour for the character, whatever connection it is: the palette's first (the character's
// number counts the connections since the server started, so a colour from it changed on every reload).
const COLOUR = COLOURS[0];
const NONE = '\u2014';       // a read-out with no data yet
// The released network's styles 095-099 were fine-tuned on the five styles held out of training
// (Roadrunner, ShieldedLeft, Skip, Star, WildArms); which id is which is not documented
// (docs/original-code.md, the data folder's README). Alphabetical, as 000-094 are, is the guess
// shown ("probably"): it agrees with how the three most distinctive ones move when walked with the
// demo's character (097's hips bounce most, 098 holds arms and feet widest, 099's hands move
// fastest), and nothing measured contradicts it for 095 and 096.
const HELD_OUT = { '095': 'Roadrunner', '096': 'ShieldedLeft', '097': 'Skip', '098': 'Star', '099': 'WildArms' };
const HELD_OUT_IDS = Object.keys(HELD_OUT);

const demo = {
  ready: false, connected: false, closed: false, hello: null, frame: null, frames: 0,
  refused: null, errors: [], notices: [], latencyMs: null, sent: 0, paused: false, cameraMode: 'follow',
  recordings: [], lastRecording: null, colour: COLOUR,
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
  else if (m.type === 'recording') onRecording(m);
  else if (m.type === 'recordingGif') onRecordingGif(m);
  else if (m.type === 'error') {
    demo.errors.push(m); toast('refused: ' + m.message, 'error');
    if (m.seq !== null && m.seq === recordPending) { recordPending = null; $('recordStatus').textContent = m.message; }
  }
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

let stage = null, actor = null, body = null, label = null, floor = null, trail = null, arrow = null, SIZE = 1.7;
let ahead = null;   // the path ahead (pathAhead): {group, dots (predicted samples), ticks (their facing), path (the keys' line)}
let heldOut = new Set();
const orbit = { target: new THREE.Vector3(0, 0.9, 0), radius: 5, azimuth: Math.PI + 0.5, elevation: 0.3 };
// azimuth offset from behind the body's facing, the azimuth last set, the azimuth it swings
// towards and the frame that was worked out from
const chase = { offset: 0.5, set: Math.PI + 0.5, goal: null, aimedAt: null };
const TRAIL = 600;                                    // the root's last 10 s at 60 fps
const trailPoints = [];

function setup(h) {
  demo.hello = h;
  SIZE = h.size || 1.7;
  stage = createStage($('view'), $('message'), SIZE);
  floor = addFloor(stage.scene, SIZE, 60, 0.5);
  const group = new THREE.Group();
  stage.scene.add(group);
  actor = skeletonKit(SIZE).build(group, h.parents, COLOUR);
  body = mannequinKit(SIZE).build(group, h.parents, COLOUR, h.body);   // h.body: the body plan
  showBody();
  ahead = pathAhead(stage.scene);
  showPath();
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * TRAIL), 3));
  trail = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: 0x8890a0 }));
  stage.scene.add(trail);
  arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, 0x2ca02c, 0.15, 0.08);
  stage.scene.add(arrow);
  orbit.radius = 3.2 * SIZE;
  orbitControls(stage.renderer.domElement, orbit, stage.camera, SIZE, () => setCamera('free'));
  window.addEventListener('resize', stage.resize);
  stage.resize();

  heldOut = new Set(h.styles.length === 100 && HELD_OUT_IDS.every(n => h.styles.includes(n)) ? HELD_OUT_IDS : []);
  for (const id of ['style', 'corner0', 'corner1', 'corner2']) {
    const heldOutGroup = document.createElement('optgroup');
    heldOutGroup.label = 'fine-tuned on the 5 held-out styles (which is which: a guess, not documented)';
    for (const name of h.styles) {
      const option = new Option(displayName(name), name);
      option.dataset.search = (heldOut.has(name) ? `${name} ${HELD_OUT[name]} held-out fine-tuned` : name).toLowerCase();
      (heldOut.has(name) ? heldOutGroup : $(id)).appendChild(option);
    }
    if (heldOutGroup.children.length) $(id).appendChild(heldOutGroup);
  }
  const start = Object.keys(h.style)[0];
  $('style').value = start;
  search();
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
  const now = performance.now();
  if (f.ack !== null && sentAt.size) {
    for (const [s, at] of sentAt) {
      if (s <= f.ack) {
        // the first frame made with this input: the time from the user's input to motion
        if (s === f.ack && inputSeqs.has(s)) demo.latencyMs = now - at;
        sentAt.delete(s);
        inputSeqs.delete(s);
      }
    }
  }
  frameTimes.push(f.frameMs);
  if (frameTimes.length > 60) frameTimes.shift();
  if (firstArrival === null) firstArrival = now;
  arrivals.push(now);
  while (arrivals[0] < now - 1000) arrivals.shift();
  // "back to the start": the path so far ends with the first frame made after the reset (until
  // then the frames in flight still continue it), so no line joins the old place to the start
  if (resetSeq !== null && f.ack !== null && f.ack >= resetSeq) { trailPoints.length = 0; resetSeq = null; }
  const n = trailPoints.length;
  if (n && Math.hypot(f.root[0] - trailPoints[n - 3], f.root[1] - trailPoints[n - 1]) > 1.0) trailPoints.length = 0;
  trailPoints.push(f.root[0], 0.003 * SIZE, f.root[1]);
  if (trailPoints.length > 3 * TRAIL) trailPoints.splice(0, 3);
  fresh = true;
}

let fresh = false, firstArrival = null, resetSeq = null;
const frameTimes = [], arrivals = [], inputSeqs = new Set();

function pose() {
  const f = demo.frame, p = f.positions;
  const top = poseSkeleton(actor, (j, out) => out.set(p[3 * j], p[3 * j + 1], p[3 * j + 2]));
  const toes = demo.hello.contactJoints.filter((j, k) => f.contacts[k] >= 0.5);
  toes.forEach(j => highlightJoint(actor, j));
  poseMannequin(body, actor, toes);
  if (!label) setLabel(mixText(f.weights));   // its text follows the mix in readouts(), 10 times a second
  label.position.set(f.root[0], top + 0.12 * SIZE, f.root[1]);
  // The trail's points change every frame, and three.js culls a line by its bounding sphere, which
  // it computes once (at the first draw, around the origin) and never again: without this the
  // line vanished once the character had walked a few metres away from where it started.
  const a = trail.geometry.attributes.position;
  a.array.set(trailPoints);
  a.needsUpdate = true;
  trail.geometry.setDrawRange(0, trailPoints.length / 3);
  trail.geometry.computeBoundingSphere();
  if (ahead.group.visible) placePath(f);
  const v = f.velocity, speed = Math.hypot(v[0], v[1]);
  arrow.visible = speed > 1e-3;
  if (arrow.visible) {
    arrow.position.set(f.root[0], 0.01 * SIZE, f.root[1]);
    arrow.setDirection(new THREE.Vector3(v[0] / speed, 0, v[1] / speed));
    arrow.setLength(0.25 + 0.35 * speed, 0.15, 0.08);
  }
}

// The path ahead, as AI4Animation's demos draw it: the network's predicted trajectory (a dot at
// each future sample, 0, 0.2, .., 1 s ahead, with a tick along the facing it predicts there) and,
// as a green line, where the held keys lead over the same second (minifilm/demo/paths.py).
// The checkbox or T shows or hides it. Its buffers are made at the first frame (S samples) and
// then only rewritten: a new buffer every frame would pile up on the GPU.
function pathAhead(scene) {
  const group = new THREE.Group();
  scene.add(group);
  const material = new THREE.MeshBasicMaterial({ color: 0x2b3040 });
  return { group, material, dot: new THREE.SphereGeometry(0.02 * SIZE, 10, 6), dots: [], ticks: null, path: null };
}

function placePath(f) {
  const S = f.future.length / 2, N = f.path.length / 2, y = 0.006 * SIZE, tick = 0.12 * SIZE;
  if (!ahead.ticks) {
    const line = (Kind, n, colour) => {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * n), 3));
      const l = new Kind(geometry, new THREE.LineBasicMaterial({ color: colour }));
      l.frustumCulled = false;   // its points move every frame (see the trail in pose())
      ahead.group.add(l);
      return l;
    };
    ahead.ticks = line(THREE.LineSegments, 2 * S, 0x2b3040);
    ahead.path = line(THREE.Line, N, 0x2ca02c);
    for (let s = 0; s < S; s++) { const m = new THREE.Mesh(ahead.dot, ahead.material); ahead.group.add(m); ahead.dots.push(m); }
  }
  const t = ahead.ticks.geometry.attributes.position, p = ahead.path.geometry.attributes.position;
  for (let s = 0; s < S; s++) {
    const x = f.future[2 * s], z = f.future[2 * s + 1];
    ahead.dots[s].position.set(x, y, z);
    t.setXYZ(2 * s, x, y, z);
    t.setXYZ(2 * s + 1, x + tick * f.futureFacing[2 * s], y, z + tick * f.futureFacing[2 * s + 1]);
  }
  for (let k = 0; k < N; k++) p.setXYZ(k, f.path[2 * k], y, f.path[2 * k + 1]);
  t.needsUpdate = p.needsUpdate = true;
}

function showPath() {
  if (!ahead) return;
  ahead.group.visible = $('path').checked;
  if (ahead.group.visible && demo.frame) placePath(demo.frame);
}
$('path').addEventListener('change', e => { showPath(); e.target.blur(); });

function setLabel(text) {
  const where = label ? label.position.clone() : null;   // a new text keeps its place above the head
  if (label) { stage.scene.remove(label); label.material.map.dispose(); label.material.dispose(); }
  label = makeLabel(text, COLOUR);
  if (where) label.position.copy(where);
  label.userData.text = text;
  stage.scene.add(label);
}

// The body (mannequin) and the sticks: each on or off; with neither the sticks are shown.
function showBody() {
  if (!body) return;
  setMannequinVisible(body, $('body').checked);
  setSkeletonVisible(actor, $('sticks').checked || !$('body').checked || !body.plan);
}
for (const id of ['body', 'sticks']) $(id).addEventListener('change', e => { showBody(); e.target.blur(); });

// A style as the user knows it: the held-out ids say what they are.
function displayName(name) {
  return heldOut.has(name) ? `${name} (probably ${HELD_OUT[name]}, held-out)` : name;
}

// A mix as a user reads it: "Neutral 60 % + Old 40 %", or just the name of a single style.
function mixText(weights) {
  const parts = Object.entries(weights).filter(([, w]) => w >= 0.005).sort((a, b) => b[1] - a[1]);
  if (parts.length <= 1) return parts.length ? displayName(parts[0][0]) : '';
  return parts.map(([n, w]) => `${displayName(n)} ${Math.round(100 * w)} %`).join(' + ');
}

// ---------------------------------------------------------------------------------------------
// Read-outs: speeds, frame time, the style mix, four local-phase dials (the paper's Figure 4)
// ---------------------------------------------------------------------------------------------

const median = xs => { const s = [...xs].sort((a, b) => a - b); return s.length ? s[s.length >> 1] : NaN; };
const phaseScale = [1e-3, 1e-3, 1e-3, 1e-3];

function readouts() {
  const f = demo.frame;
  // each value in its own fixed cell, the note on lines of its own kept for it: nothing moves
  $('commanded').textContent = `${f.commanded.toFixed(2)} m/s`;
  $('reachable').textContent = `${f.reachable.toFixed(2)} m/s`;
  $('speedNote').textContent = f.speedNote || '';
  $('speedNote').title = f.speedNote || '';
  $('actual').textContent = `${f.speed.toFixed(2)} m/s`;
  $('frametime').textContent = `${median(frameTimes).toFixed(2)} ms`;   // median of the last 60
  // frames that arrived in the last second, once the page has been receiving for a second
  const now = performance.now();
  while (arrivals.length && arrivals[0] < now - 1000) arrivals.shift();
  demo.framesPerSecond = now - firstArrival >= 1000 ? arrivals.length : null;
  $('fps').textContent = demo.framesPerSecond === null ? NONE : `${demo.framesPerSecond} / s`;
  $('latency').textContent = demo.latencyMs === null ? NONE : `${demo.latencyMs.toFixed(0)} ms`;
  realTime(f);
  showPicked(f.target);
  const text = mixText(f.weights);
  if (!label || label.userData.text !== text) setLabel(text);
  const mix = Object.entries(f.weights).sort((a, b) => b[1] - a[1]).map(([n, w]) => `${displayName(n)} ${w.toFixed(2)}`);
  const target = mixText(f.target);
  const arrived = Object.keys(f.target).length === Object.keys(f.weights).length &&
    Object.entries(f.target).every(([n, w]) => Math.abs((f.weights[n] ?? -1) - w) < 0.005);
  $('mix').textContent = `now ${mix.join(' · ')}` + (arrived ? '' : ` → ${target}`) +
    (f.calibrated ? '' : f.calibration && f.calibration.state === 'measuring' ? ` (speed calibration: ${f.calibration.done} of ${f.calibration.total} measured, ${f.calibration.measuring || ''} on its way)` : ' (speed calibration on its way)');
  for (let k = 0; k < 4; k++) dial(k, f.phases[2 * k], f.phases[2 * k + 1]);
}

// Does the simulation keep up with the clock (the server batches steps when it falls behind,
// frame_loop.py)? Network steps per wall second, and the steps it is behind or dropped.
function realTime(f) {
  if (f.stepsPerSecond === undefined) return;
  const late = (f.dropped || 0) > 0;
  $('realtime').textContent = `${f.stepsPerSecond} steps / s` +
    (late ? `: ${f.dropped} dropped in the last second, slow motion (the machine is too busy)`
      : f.behind > 0 ? `, ${f.behind} behind, catching up` : '');
  $('realtime').classList.toggle('warn', late);
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
// Nothing held is what the server starts with: nothing is sent until the user holds something.
let lastInput = JSON.stringify({ type: 'input', move: [0, 0], turn: 0, speed: 0 });

function typing(e) {
  const t = e.target;
  return t && (t.tagName === 'SELECT' || (t.tagName === 'INPUT' && (t.type === 'text' || t.type === 'search')));
}

// Keys that are not movement: camera, pause, body, sticks, record.
const COMMANDS = {
  Digit1: () => setCamera('follow'), Digit2: () => setCamera('front'), Digit3: () => setCamera('side'),
  KeyP: () => setPaused(!demo.paused), KeyR: () => record(),
  KeyB: () => { $('body').checked = !$('body').checked; showBody(); },
  KeyK: () => { $('sticks').checked = !$('sticks').checked; showBody(); },
  KeyT: () => { $('path').checked = !$('path').checked; showPath(); },
};

window.addEventListener('keydown', e => {
  if (COMMANDS[e.code] && !typing(e) && !e.repeat && !e.ctrlKey && !e.metaKey && !e.altKey) {
    e.preventDefault(); COMMANDS[e.code](); return;
  }
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
  const s = send(input);
  if (s !== null) { lastInput = key; inputSeqs.add(s); }   // not yet connected: try again next frame
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
$('style').addEventListener('change', e => { if (e.target.value) setStyle(e.target.value); e.target.blur(); });

// The picker shows where the style is going: one style, or the blend ("Neutral 60 % + Old 40 %")
// as a first entry that cannot be picked. Not while the user has the list open.
function showPicked(target) {
  const select = $('style'), names = Object.keys(target);
  if (document.activeElement === select) return;
  const mix = $('mixOption');
  if (names.length === 1) {
    mix.hidden = true;
    if (select.value !== names[0]) select.value = names[0];
  } else {
    mix.textContent = mixText(target);
    mix.hidden = false;
    select.value = '';
  }
}

// The search box keeps the styles whose name (or, for the held-out ids, what is known of them)
// contains what is typed; Enter picks the first one left.
function search() {
  const words = $('search').value.trim().toLowerCase().split(/\s+/).filter(Boolean);
  const options = [...$('style').querySelectorAll('option')].filter(o => o.id !== 'mixOption');
  let shown = 0;
  for (const o of options) {
    o.hidden = !words.every(w => o.dataset.search.includes(w));
    if (!o.hidden) shown++;
  }
  for (const g of $('style').querySelectorAll('optgroup')) g.hidden = ![...g.children].some(o => !o.hidden);
  $('found').textContent = words.length ? (shown ? `${shown} of ${options.length} styles` : 'no style matches') : '';
  return options.filter(o => !o.hidden).map(o => o.value);
}
$('search').addEventListener('input', search);
$('search').addEventListener('keydown', e => {
  if (e.key === 'Enter') {
    const found = search();
    if (found.length) { setStyle(found[0]); e.target.blur(); }
  } else if (e.key === 'Escape') { e.target.value = ''; search(); e.target.blur(); }
});

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

// A window too short for every section (800 x 600, or even 1280 x 900): the recorder, then the
// blend triangle, then the phase dials start folded (their titles open them) until the rest fits
// without scrolling, so the settings, the read-outs and the view are all in sight.
function foldToFit() {
  const panel = $('panel');
  for (const id of ['sec-record', 'sec-blend', 'sec-phases']) {
    if (panel.scrollHeight <= panel.clientHeight) break;
    $(id).open = false;
  }
}
foldToFit();
for (const s of document.querySelectorAll('#panel summary')) s.addEventListener('click', e => e.currentTarget.blur());

for (const name of ['footLock', 'fit']) {
  $(name).addEventListener('change', e => { send({ type: 'settings', [name]: e.target.checked }); e.target.blur(); });
}
$('reset').addEventListener('click', e => {
  const s = send({ type: 'reset' });
  if (s !== null) resetSeq = s;           // the trail starts again with the first frame after it (onFrame)
  e.target.blur();
});

// ---------------------------------------------------------------------------------------------
// Camera modes (follow: behind the body; front; side; free: after a pan), pause
// ---------------------------------------------------------------------------------------------

// offset of the camera's azimuth from behind the body's facing, and its elevation (radians)
const CAMERA = { follow: { offset: 0.5, elevation: 0.3 }, front: { offset: -Math.PI, elevation: 0.1 },
                 side: { offset: -Math.PI / 2, elevation: 0.1 } };

function setCamera(mode) {
  demo.cameraMode = mode;
  if (CAMERA[mode]) {
    chase.offset = CAMERA[mode].offset;
    orbit.elevation = CAMERA[mode].elevation;
  }
  for (const b of document.querySelectorAll('button.camera')) b.classList.toggle('on', b.dataset.mode === mode);
}
for (const b of document.querySelectorAll('button.camera')) {
  b.addEventListener('click', e => { setCamera(b.dataset.mode); e.target.blur(); });
}

// Pause freezes the picture (the camera still orbits); the character goes on on the server.
function setPaused(on) {
  demo.paused = on;
  $('pause').textContent = on ? 'resume' : 'pause';
  $('pause').classList.toggle('on', on);
}
$('pause').addEventListener('click', e => { setPaused(!demo.paused); e.target.blur(); });

// ---------------------------------------------------------------------------------------------
// Record: the server keeps each character's last 30 s; the page asks for the last few seconds and
// downloads the BVH it answers with (and offers the GIF when the server could make one)
// ---------------------------------------------------------------------------------------------

let recordPending = null;

function record() {
  if (recordPending !== null || !demo.ready) return null;
  const seconds = Number($('recordSeconds').value);
  const s = send({ type: 'record', seconds, gif: true });
  if (s === null) return null;
  recordPending = s;
  $('recordStatus').textContent = `making the last ${seconds} s\u2026`;
  return s;
}
$('record').addEventListener('click', e => { record(); e.target.blur(); });

function download(data, name, type) {
  const url = URL.createObjectURL(new Blob([data], { type }));
  const a = document.createElement('a');
  a.href = url; a.download = name;
  document.body.appendChild(a); a.click(); a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 60000);
  return url;
}

function onRecording(m) {
  if (m.seq === recordPending) recordPending = null;
  const style = demo.frame ? mixText(demo.frame.weights).replace(/[^A-Za-z0-9]+/g, '-').replace(/^-|-$/g, '') : 'demo';
  const stamp = new Date().toISOString().slice(0, 19).replace(/[:T]/g, '-');
  const name = `minifilm-${style}-${stamp}`;
  demo.lastRecording = { seq: m.seq, frames: m.frames, seconds: m.seconds, fps: m.fps, bvh: m.bvh,
                         gif: m.gif ? 'coming' : null, note: '', name };
  demo.recordings.push(name);
  download(m.bvh, name + '.bvh', 'text/plain');
  $('recordStatus').textContent = `saved ${name}.bvh (${m.frames} frames, ${m.seconds.toFixed(1)} s)` +
    (m.gif ? ' \u00b7 making the GIF\u2026' : '');
}

// The GIF comes later (drawn on the server in a process of its own): a link to save it, or why not.
function onRecordingGif(m) {
  const rec = demo.lastRecording;
  if (!rec || rec.seq !== m.seq) return;
  const status = $('recordStatus');
  status.textContent = status.textContent.replace(' \u00b7 making the GIF\u2026', '');
  rec.note = m.note;
  if (m.gif !== null) {
    const bytes = Uint8Array.from(atob(m.gif), c => c.charCodeAt(0));
    rec.gif = bytes.length;
    const a = document.createElement('a');
    a.href = URL.createObjectURL(new Blob([bytes], { type: 'image/gif' }));
    a.download = rec.name + '.gif';
    a.textContent = `GIF (${Math.round(bytes.length / 1024)} KB)`;
    status.append(' \u00b7 ', a);
  } else {
    rec.gif = null;
    status.append(` \u00b7 ${m.note}`);
  }
}

// ---------------------------------------------------------------------------------------------
// Main loop: poll the gamepad, pose the newest frame, chase it with the camera, draw
// ---------------------------------------------------------------------------------------------

const angle = a => Math.atan2(Math.sin(a), Math.cos(a));
let last = null, lastReadout = 0;

function tick(now) {
  const dt = last === null ? 0 : Math.min((now - last) / 1000, 0.1);
  last = now;
  sendInput();   // picks up the gamepad; keys are sent as they change
  if (demo.frame && fresh && !demo.paused) {
    pose();
    fresh = false;
  }
  if (demo.frame && now - lastReadout > 100) { readouts(); lastReadout = now; }
  if (demo.frame && CAMERA[demo.cameraMode] && !demo.paused) {
    const f = demo.frame, k = dt > 0 ? 1 - Math.exp(-dt / 0.15) : 1;
    orbit.target.lerp(new THREE.Vector3(f.root[0], 0.5 * SIZE, f.root[1]), k);
    // behind the body's facing (the root's, as the network moves it), plus whatever the user
    // dragged the camera round by. Not the steered heading: on Q/E that runs up to half a turn
    // ahead of the body, and the camera swung round to look at the character's side.
    chase.offset += angle(orbit.azimuth - chase.set);
    const behind = Math.atan2(f.facing[0], f.facing[1]) + Math.PI + chase.offset;
    chase.goal = behind; chase.aimedAt = f;
    orbit.azimuth = chase.set + angle(behind - chase.set) * (dt > 0 ? 1 - Math.exp(-dt / CHASE_SECONDS) : 1);
    chase.set = orbit.azimuth;
  }
  const cell = floor.cell;   // the floor moves under the camera by whole cells: it looks endless
  floor.ground.position.set(Math.round(orbit.target.x / cell) * cell, 0, Math.round(orbit.target.z / cell) * cell);
  floor.grid.position.set(floor.ground.position.x, floor.grid.position.y, floor.ground.position.z);
  placeCamera(stage.camera, orbit);
  stage.renderer.render(stage.scene, stage.camera);
  drawTimes.push(now);
  if (drawTimes.length > 1200) drawTimes.shift();
  requestAnimationFrame(tick);
}
const drawTimes = [];   // requestAnimationFrame times of the last 1200 drawn frames (the page's own cost)

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
  // The path ahead as drawn: shown or not, its dots (world x, y, z) and the held keys' line.
  pathAhead: () => ({ visible: ahead.group.visible, dots: ahead.dots.map(m => m.position.toArray()),
                      path: ahead.path ? [...ahead.path.geometry.attributes.position.array] : [] }),
  setCamera,                              // ('follow' | 'front' | 'side' | 'free')
  setPaused,                              // (bool)
  record,                                 // () -> seq of the record message (null if one is on its way)
  search: text => { $('search').value = text; return search(); },   // -> the style names left
  mixText,                                // ({name: weight}) -> "Neutral 60 % + Old 40 %"
  // The trail as drawn: its drawRange count, those points (x, y, z flat), whether three.js may cull
  // it, whether the camera sees its bounding sphere and whether that sphere holds the newest point.
  trail() {
    const g = trail.geometry;
    if (!g.boundingSphere) g.computeBoundingSphere();
    const frustum = new THREE.Frustum().setFromProjectionMatrix(new THREE.Matrix4().multiplyMatrices(
      stage.camera.projectionMatrix, stage.camera.matrixWorldInverse));
    const last = new THREE.Vector3().fromArray(g.attributes.position.array, Math.max(0, 3 * g.drawRange.count - 3));
    return { count: g.drawRange.count, points: [...g.attributes.position.array.slice(0, 3 * g.drawRange.count)],
             culled: trail.frustumCulled,
             inView: frustum.intersectsSphere(g.boundingSphere), boundsHoldLast: g.boundingSphere.distanceToPoint(last) < 1e-4 };
  },
  // Meshes in the scene now drawn, by kind: {body, sticks} (the mannequin's, the skeleton's).
  visibleMeshes: () => ({ body: body.all.filter(m => m.visible).length,
                          sticks: [...actor.joints, ...actor.bones.map(b => b[0])].filter(m => m.visible).length }),
  label: () => (label ? { text: label.userData.text, position: label.position.toArray() } : null),
  // ms between the last drawn frames (requestAnimationFrame; those drawn after performance.now()
  // ``since``), the page's own frame time.
  drawIntervals: (since = -Infinity) => drawTimes.slice(1).map((t, i) => [t, t - drawTimes[i]]).filter(([t]) => t > since)
    .map(([, d]) => d),
  // What three.js drew in the last frame: triangles, draw calls, meshes shown.
  renderInfo() {
    let meshes = 0;
    stage.scene.traverseVisible(o => { if (o.isMesh) meshes++; });
    const r = stage.renderer.info.render;
    return { triangles: r.triangles, calls: r.calls, meshes };
  },
  // Joint positions the page shows now ((J, 3), metres, world).
  shownJoints: () => actor.joints.map(m => [m.position.x, m.position.y, m.position.z]),
  // The orbit camera now: azimuth (radians about +y), the point it looks at, the mode, the offset
  // of its azimuth from straight behind the facing (0.5 rad in follow mode) and the azimuth it
  // swings towards, with the facing and heading of the frame that goal was worked out from (null
  // until a frame was drawn in a following mode).
  camera: () => ({ azimuth: orbit.azimuth, target: orbit.target.toArray(), position: stage.camera.position.toArray(),
                   mode: demo.cameraMode, offset: chase.offset, goal: chase.goal,
                   facing: chase.aimedAt && chase.aimedAt.facing, heading: chase.aimedAt && chase.aimedAt.heading }),
  shownColour: () => actor.material.color.getHex(),   // the character's colour (sRGB, 0xrrggbb)
});
