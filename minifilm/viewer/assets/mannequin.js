// minifilm mannequin: a character drawn as a shaded body (capsule limbs, a head, a soft shadow on
// the floor) instead of sticks. Shared by the motion player (player.js) and the live demo
// (minifilm/demo/assets/demo.js); it poses itself from a stick skeleton of scene.js (its joint
// meshes hold the joint positions), so both drawings always show the same pose.
//
//   mannequinKit(size)                 shared geometries and the shadow texture
//   kit.build(group, parents, colour, names)  one body's meshes inside ``group`` (hidden until posed)
//   poseMannequin(body, sk, contacts)  limbs, head and shadow from skeleton ``sk``'s joints;
//                                      ``contacts``: joint indices to draw in the contact colour
//
// Which bone is torso, neck, head, arm or leg comes from the hierarchy and the first pose, not from
// joint names, so any humanoid rig gets a body: the spine is the chain from the root that always
// climbs to the highest child; the head sits on the spine joint named "head" if there is one (a
// rig may go on above it to an end site or the eyes: those bones are inside the head), else on its
// last joint; the joint where most branches leave the spine is the chest (bones above it are the
// neck); a branch that reaches down to the lower half of the hips' height is a leg, any other an
// arm. A limb's segments get thinner away from the body.
// Everything is in metres, y up; ``size`` (the body's height) scales every radius.
import * as THREE from 'three';
import { CONTACT_COLOUR } from 'minifilm-scene';

const UP = new THREE.Vector3(0, 1, 0);
// Radii as fractions of the body size (a 1.7 m person: torso 11 cm, thigh 6.8 cm, head 10.5 cm).
const RADIUS = { torso: 0.064, hips: 0.066, pelvis: 0.048, neck: 0.027, head: 0.062, leg: 0.040, arm: 0.027,
                 shoulder: 0.030 };
const TAPER = { leg: 0.8, arm: 0.86 };   // each segment down a limb is this much thinner than the last

function lighter(colour, amount) {
  return new THREE.Color(colour).lerp(new THREE.Color(0xffffff), amount);
}

// A soft round shadow: a radial gradient, dark in the middle, transparent at the rim.
function shadowTexture() {
  const canvas = document.createElement('canvas');
  canvas.width = canvas.height = 64;
  const g = canvas.getContext('2d');
  const gradient = g.createRadialGradient(32, 32, 0, 32, 32, 32);
  gradient.addColorStop(0, 'rgba(20, 24, 32, 0.55)');
  gradient.addColorStop(0.55, 'rgba(20, 24, 32, 0.28)');
  gradient.addColorStop(1, 'rgba(20, 24, 32, 0)');
  g.fillStyle = gradient;
  g.fillRect(0, 0, 64, 64);
  return new THREE.CanvasTexture(canvas);
}

export function mannequinKit(size) {
  const limb = new THREE.CylinderGeometry(1, 1, 1, 12, 1, true);
  limb.translate(0, 0.5, 0);                  // spans y in [0, 1]: scaled to the bone, from the parent
  const ball = new THREE.SphereGeometry(1, 14, 10);   // software WebGL pays for every triangle
  const blob = new THREE.PlaneGeometry(1, 1);
  blob.rotateX(-Math.PI / 2);                 // lies on the floor
  const shadowMap = shadowTexture();
  const contactMaterial = new THREE.MeshStandardMaterial({ color: CONTACT_COLOUR, roughness: 0.5 });

  function build(group, parents, colour, names = []) {
    const skin = new THREE.MeshStandardMaterial({ color: lighter(colour, 0.45), roughness: 0.62, metalness: 0.0 });
    const joint = new THREE.MeshStandardMaterial({ color: lighter(colour, 0.15), roughness: 0.55, metalness: 0.0 });
    const children = parents.map(() => []);
    parents.forEach((p, j) => { if (p >= 0) children[p].push(j); });
    const limbs = [], balls = [];
    for (let j = 0; j < parents.length; j++) {
      balls.push(new THREE.Mesh(ball, joint));
      if (parents[j] >= 0) limbs.push({ mesh: new THREE.Mesh(limb, skin), j, p: parents[j], r: 0 });
    }
    const head = new THREE.Mesh(ball, skin);
    const nose = new THREE.Mesh(ball, joint);  // which way the face looks: front and back differ
    const shadow = new THREE.Mesh(blob, new THREE.MeshBasicMaterial({ map: shadowMap, transparent: true,
                                                                      depthWrite: false, toneMapped: false }));
    shadow.renderOrder = -1;                   // under the character, over the floor
    const all = [...limbs.map(l => l.mesh), ...balls, head, nose, shadow];
    for (const m of all) { m.visible = false; group.add(m); }
    return { parents, names, children, limbs, balls, head, nose, shadow, all, toes: [], joint, contactMaterial, shaped: false,
             ballRadius: [], headJoint: -1, neckJoint: -1, visible: true, size };
  }

  return { build };
}

// Decide each bone's radius from the hierarchy and the first pose (see the top of this file).
function shape(body, positions) {
  const { parents, children } = body, J = parents.length, s = body.size;
  const root = parents.indexOf(-1);
  const spine = [root];
  for (let j = root; children[j].length;) {
    const up = children[j].filter(c => positions[c].y > positions[j].y - 0.02 * s);
    if (!up.length) break;
    j = up.reduce((a, b) => (positions[b].y > positions[a].y ? b : a));
    spine.push(j);
  }
  const onSpine = new Set(spine);
  // the head: on the spine joint named so, else the spine's last; what is above it (an end site,
  // the eyes) is inside the head and gets no limb or ball of its own
  const named = spine.findIndex((j, k) => k > 0 && /head/i.test(body.names[j] || '') && !/site|end/i.test(body.names[j]));
  const headAt = named > 0 ? named : spine.length - 1;
  const inHead = new Set();
  const within = j => { inHead.add(j); children[j].forEach(within); };
  children[spine[headAt]].forEach(within);
  // the chest: the spine joint below the head (root excluded) where most branches leave; the neck is above it
  let chest = -1;
  for (const j of spine.slice(1, headAt)) if (chest < 0 || children[j].length > children[chest].length) chest = j;
  const chestAt = chest < 0 ? spine.length : spine.indexOf(chest);
  const radius = new Array(J).fill(0);         // of the bone ending at joint j
  spine.forEach((j, k) => { if (k > 0) radius[j] = (k <= chestAt ? RADIUS.torso : RADIUS.neck) * s; });
  // the limbs: depth-first from every branch that leaves the spine below the head
  const visit = (j, r, taper) => {
    radius[j] = r;
    for (const c of children[j]) visit(c, r * taper, taper);
  };
  // a leg reaches down to the lower half of the hips' height (a hanging hand stays near the hips)
  const lowest = Math.min(...positions.map(p => p.y));
  const reach = j => Math.min(positions[j].y, ...children[j].map(reach));
  for (const j of spine.slice(0, headAt)) {
    for (const c of children[j]) {
      if (onSpine.has(c)) continue;
      const leg = reach(c) - lowest < 0.5 * (positions[root].y - lowest);
      if (leg) {
        let tip = c;                                                    // the foot's last joint points forward
        while (children[tip].length) tip = children[tip][0];
        if (parents[tip] !== j) body.toes.push(tip);
        radius[c] = j === root ? RADIUS.pelvis * s : RADIUS.leg * s;   // the hip joint's offset from the root
        for (const g of children[c]) visit(g, RADIUS.leg * s, TAPER.leg);
      } else {
        radius[c] = RADIUS.shoulder * s;                                // collar bone
        for (const g of children[c]) visit(g, RADIUS.arm * s, TAPER.arm);
      }
    }
  }
  for (const j of inHead) radius[j] = 0;
  for (const l of body.limbs) l.r = radius[l.j];
  // a ball at every joint as thick as the thickest bone there: the limbs' rounded ends
  body.ballRadius = Array.from({ length: J }, (_, j) =>
    (inHead.has(j) ? 0 : Math.max(radius[j], ...children[j].map(c => radius[c]), 0.012 * s)));
  body.ballRadius[root] = Math.max(body.ballRadius[root], RADIUS.hips * s);
  body.headJoint = spine[headAt];
  body.neckJoint = headAt > 0 ? spine[headAt - 1] : -1;
  body.ballRadius[body.headJoint] = RADIUS.neck * s;
  body.shaped = true;
}

const tmp = new THREE.Vector3(), centre = new THREE.Vector3(), facing = new THREE.Vector3();

export function setMannequinVisible(body, on) {
  body.visible = on;
  for (const m of body.all) m.visible = on && body.shaped;
}

export function poseMannequin(body, sk, contacts = []) {
  const P = sk.joints.map(m => m.position);
  if (!body.shaped) { shape(body, P); setMannequinVisible(body, body.visible); }
  if (!body.visible) return;
  const s = body.size;
  for (const l of body.limbs) {
    const from = P[l.p];
    tmp.subVectors(P[l.j], from);
    const length = tmp.length();
    l.mesh.visible = length > 1e-4 * s && l.r > 0;
    if (!l.mesh.visible) continue;
    l.mesh.position.copy(from);
    l.mesh.quaternion.setFromUnitVectors(UP, tmp.divideScalar(length));
    l.mesh.scale.set(l.r, length, l.r);
  }
  body.balls.forEach((b, j) => {
    b.visible = body.ballRadius[j] > 0;
    b.position.copy(P[j]);
    b.scale.setScalar(body.ballRadius[j]);
    b.material = body.joint;
  });
  for (const j of contacts) {
    body.balls[j].material = body.contactMaterial;
    body.balls[j].scale.setScalar(Math.max(body.ballRadius[j], 0.025 * s));
  }
  // the head: above its joint along the neck, a little taller than wide
  const h = body.headJoint, r = RADIUS.head * s;
  if (body.neckJoint >= 0) tmp.subVectors(P[h], P[body.neckJoint]).normalize();
  else tmp.copy(UP);
  body.head.position.copy(P[h]).addScaledVector(tmp, 0.75 * r);
  body.head.quaternion.setFromUnitVectors(UP, tmp);
  body.head.scale.set(0.86 * r, r, 0.92 * r);
  // the nose: in front of the head, the way the feet point (the last bone of each leg)
  facing.set(0, 0, 0);
  for (const t of body.toes) facing.add(tmp.subVectors(P[t], P[body.parents[t]]).setY(0));
  body.nose.visible = body.visible && facing.lengthSq() > 1e-8;
  if (body.nose.visible) {
    body.nose.position.copy(body.head.position).addScaledVector(facing.normalize(), 0.95 * r);
    body.nose.position.y -= 0.1 * r;
    body.nose.scale.set(0.24 * r, 0.24 * r, 0.24 * r);
  }
  // the shadow: under the body's middle, as wide as the body spreads, fainter as it leaves the floor
  centre.set(0, 0, 0);
  let low = Infinity;
  for (const p of P) { centre.add(p); low = Math.min(low, p.y); }
  centre.divideScalar(P.length);
  let spread = 0;
  for (const p of P) spread = Math.max(spread, Math.hypot(p.x - centre.x, p.z - centre.z));
  const width = 2 * spread + 0.35 * s;
  body.shadow.position.set(centre.x, 0.002 * s, centre.z);
  body.shadow.scale.set(width, 1, width);
  body.shadow.material.opacity = Math.max(0.25, 1 - Math.max(0, low) / (0.5 * s));
}
