// minifilm scene: the three.js pieces both pages draw with, the motion player (player.js, a file
// opened from disk) and the live demo (minifilm/demo/assets/demo.js, served by the demo server).
//
//   createStage(view, messageBox, size)   renderer, scene, lights and camera in a container
//   addFloor(scene, size, span, grid)     ground plane and grid (span metres, cells of grid metres)
//   skeletonKit(size)                      shared geometries; kit.build(group, parents, colour)
//   poseSkeleton(sk, setJoint)             joint spheres and bone cylinders from joint positions
//   setSkeletonVisible(sk, on)             sticks shown or hidden (the mannequin, mannequin.js, reads them)
//   makeLabel(text, colour)                a name sprite of constant size on screen
//   layoutLabels(labels, camera, w, h)     lift labels that would overlap on screen; their boxes
//   labelBox(label, camera, w, h)          where a label is drawn: [left, top, right, bottom] px
//   orbitControls(el, orbit, camera, size, onPan) and placeCamera(camera, orbit)
//
// Everything is in metres, y up, in the axes of the BVH forward kinematics; ``size`` is the body
// size (metres) that scales radii, camera distances and labels.
import * as THREE from 'three';

export const COLOURS = [0x1f77b4, 0xd62728, 0x2ca02c, 0x9467bd, 0xff7f0e, 0x17becf, 0x8c564b, 0xe377c2];
export const CONTACT_COLOUR = 0xffc400;
const UP = new THREE.Vector3(0, 1, 0);

// A WebGL renderer filling ``view``, a lit scene and a perspective camera. Without WebGL the
// reason is written into ``messageBox`` (old browser, or WebGL switched off) and the error thrown.
export function createStage(view, messageBox, size) {
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: true });
  } catch (e) {
    messageBox.hidden = false;
    messageBox.textContent = 'This page needs WebGL, which this browser does not provide: ' + e.message;
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

  const camera = new THREE.PerspectiveCamera(40, 1, 0.01 * size, 2000 * size);
  function resize() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
  }
  return { renderer, scene, camera, resize };
}

// A square floor of ``span`` metres with a grid of ``grid``-metre cells, centred on the origin
// (move ``floor.ground`` and ``floor.grid`` together by whole cells to follow a character).
// Both are cut into pieces of about a cell: software WebGL (SwiftShader, the tests' renderer) drops
// a long line or a large triangle that reaches behind the camera, so a big floor in one piece
// vanished near the camera.
export function addFloor(scene, size, span, grid) {
  const cells = Math.max(1, Math.min(2000, Math.round(span / grid)));
  span = cells * grid;
  const pieces = Math.min(cells, 40);   // the plane's triangles: small enough, and not too many
  const ground = new THREE.Mesh(new THREE.PlaneGeometry(span, span, pieces, pieces),
                                new THREE.MeshLambertMaterial({ color: 0xe6e8ec }));
  ground.rotation.x = -Math.PI / 2;
  scene.add(ground);
  const gridLines = gridSegments(span, cells, new THREE.Color(0xb9bec8), new THREE.Color(0xcdd1d8));
  gridLines.position.y = 0.001 * size;  // just above the floor, so it does not flicker into it
  scene.add(gridLines);
  return { ground, grid: gridLines, cell: grid, span };
}

// The lines of THREE.GridHelper(span, cells, centre, other), each cut into one segment per cell
// (at most 40 per line: software rendering pays for every segment).
function gridSegments(span, cells, centre, other) {
  const half = span / 2, step = span / cells, pieces = Math.min(cells, 40), piece = span / pieces;
  const position = [], colour = [];
  for (let i = 0; i <= cells; i++) {
    const a = -half + i * step, c = i === cells / 2 ? centre : other;
    for (let k = 0; k < pieces; k++) {
      const b0 = -half + k * piece, b1 = b0 + piece;
      position.push(a, 0, b0, a, 0, b1, b0, 0, a, b1, 0, a);
      for (let v = 0; v < 4; v++) colour.push(c.r, c.g, c.b);
    }
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.Float32BufferAttribute(position, 3));
  geometry.setAttribute('color', new THREE.Float32BufferAttribute(colour, 3));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ vertexColors: true, toneMapped: false }));
}

// Geometries shared by every skeleton of one body size; ``build`` makes one skeleton's meshes
// inside ``group``: a sphere per joint, a cylinder per bone (joint j to parents[j] >= 0).
export function skeletonKit(size) {
  const jointGeometry = new THREE.SphereGeometry(0.022 * size, 12, 8);
  const boneGeometry = new THREE.CylinderGeometry(0.013 * size, 0.013 * size, 1, 8);
  boneGeometry.translate(0, 0.5, 0);  // spans y in [0, 1]: scaled to the bone length, from the parent
  const contactMaterial = new THREE.MeshLambertMaterial({ color: CONTACT_COLOUR });
  function build(group, parents, colour) {
    const material = new THREE.MeshLambertMaterial({ color: colour });
    const joints = [], bones = [];
    for (let j = 0; j < parents.length; j++) {
      const m = new THREE.Mesh(jointGeometry, material);
      group.add(m); joints.push(m);
      if (parents[j] >= 0) {
        const b = new THREE.Mesh(boneGeometry, material);
        group.add(b); bones.push([b, j, parents[j]]);
      }
    }
    return { material, contactMaterial, joints, bones };
  }
  return { build, contactMaterial };
}

const tmp = new THREE.Vector3();

// Place a skeleton: ``setJoint(j, vector)`` writes joint j's position into ``vector``. Resets any
// contact highlight; returns the height of the highest joint (for a label above the head).
export function poseSkeleton(sk, setJoint) {
  let top = -Infinity;
  for (let j = 0; j < sk.joints.length; j++) {
    setJoint(j, sk.joints[j].position);
    top = Math.max(top, sk.joints[j].position.y);
    sk.joints[j].material = sk.material;
    sk.joints[j].scale.setScalar(1);
  }
  for (const [mesh, j, p] of sk.bones) {
    const from = sk.joints[p].position;
    tmp.subVectors(sk.joints[j].position, from);
    const length = tmp.length();
    mesh.position.copy(from);
    if (length > 1e-9) mesh.quaternion.setFromUnitVectors(UP, tmp.divideScalar(length));
    mesh.scale.set(1, Math.max(length, 1e-9), 1);
  }
  return top;
}

// Show or hide a skeleton's sticks (its joints keep being posed: other drawings read them).
export function setSkeletonVisible(sk, on) {
  for (const m of sk.joints) m.visible = on;
  for (const [m] of sk.bones) m.visible = on;
}

// Mark joint j as in contact (yellow and larger) until the next poseSkeleton.
export function highlightJoint(sk, j) {
  sk.joints[j].material = sk.contactMaterial;
  sk.joints[j].scale.setScalar(1.8);
}

// Name labels keep a constant size on screen (sizeAttenuation off: scale is a fraction of the
// view height), so they stay readable however far the camera zooms out.
export function makeLabel(text, colour) {
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

// Where ``label`` (a makeLabel sprite) is drawn on a ``width`` x ``height`` px view, as
// [left, top, right, bottom] in px from the view's top left; null when it is behind the camera.
// A sprite without size attenuation is ``scale`` in view space times the depth, so on screen it is
// scale * (projection's focal factor) * half the view, wherever it stands.
export function labelBox(label, camera, width, height) {
  label.updateWorldMatrix(true, false);
  const p = tmp.setFromMatrixPosition(label.matrixWorld).project(camera);
  if (p.z > 1 || p.z < -1) return null;
  const P = camera.projectionMatrix.elements;
  const w = label.scale.x * P[0] * width / 2, h = label.scale.y * P[5] * height / 2;
  const x = (p.x + 1) * width / 2, y = (1 - p.y) * height / 2;     // the anchor, in px
  const c = label.center;
  return [x - c.x * w, y - (1 - c.y) * h, x + (1 - c.x) * w, y + c.y * h];
}

const LABEL_GAP = 0.15;   // of a label's height, between labels stacked above one another

// Labels of characters side by side overlap on screen when the camera is far or the window
// narrow: each visible label, in the given order, is lifted by whole rows (its own height plus a
// gap) until its box meets no box placed before it, so no two ever overlap, at any window size.
// Call after the camera is placed, before drawing; returns the boxes (null: hidden or behind).
export function layoutLabels(labels, camera, width, height) {
  camera.updateMatrixWorld();
  const placed = [], boxes = [];
  for (const label of labels) {
    label.center.y = 0;
    let box = label.visible ? labelBox(label, camera, width, height) : null;
    if (box && !box.every(Number.isFinite)) box = null;
    if (box) {
      const rise = (box[3] - box[1]) * (1 + LABEL_GAP);
      let row = 0;
      const at = r => [box[0], box[1] - r * rise, box[2], box[3] - r * rise];
      const free = b => placed.every(q => b[2] <= q[0] || q[2] <= b[0] || b[3] <= q[1] || q[3] <= b[1]);
      while (rise > 0 && row < 10000 && !free(at(row))) row++;   // ends: high enough, it is above them all
      label.center.y = -row * (1 + LABEL_GAP);      // in the sprite's own heights: row rows up
      box = at(row);
      placed.push(box);
    }
    boxes.push(box);
  }
  return boxes;
}

// Orbit camera (our own: spherical coordinates about a target). ``orbit`` = {target (Vector3),
// radius, azimuth (radians about +y, 0 = camera on +z of the target), elevation (radians)}.
export function placeCamera(camera, orbit) {
  const ce = Math.cos(orbit.elevation);
  camera.position.set(orbit.target.x + orbit.radius * ce * Math.sin(orbit.azimuth),
                      orbit.target.y + orbit.radius * Math.sin(orbit.elevation),
                      orbit.target.z + orbit.radius * ce * Math.cos(orbit.azimuth));
  camera.lookAt(orbit.target);
}

// Drag: orbit; right-drag or shift-drag: pan (then ``onPan()``, e.g. to stop following); wheel: zoom.
export function orbitControls(el, orbit, camera, size, onPan) {
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
      if (onPan) onPan();
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
    orbit.radius = THREE.MathUtils.clamp(orbit.radius * Math.exp(e.deltaY * 0.001), 0.3 * size, 500 * size);
  }, { passive: false });
}
