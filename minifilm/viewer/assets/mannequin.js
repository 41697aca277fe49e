// minifilm mannequin: a character drawn as a shaded body (capsule limbs, a head, a soft shadow on
// the floor) instead of sticks. Shared by the motion player (player.js) and the live demo
// (minifilm/demo/assets/demo.js); it poses itself from a stick skeleton of scene.js (its joint
// meshes hold the joint positions), so both drawings always show the same pose.
//
//   mannequinKit(size)                 shared geometries and the shadow texture
//   kit.build(group, parents, colour, plan)  one body's meshes inside ``group`` (hidden until posed)
//   poseMannequin(body, sk, contacts)  limbs, head and shadow from skeleton ``sk``'s joints;
//                                      ``contacts``: joint indices to draw in the contact colour
//
// Which bone is torso, neck, head, arm or leg is not worked out here: ``plan`` is the body plan
// the page was given (minifilm/viewer/body.py, from the parts minifilm/body/humanoid.py finds):
// ``parts`` (per joint: the part of the bone ending there), ``head``, ``neck`` (the joint below the
// head) and ``toes``. A skeleton without a plan (not a humanoid) gets no body: its sticks are drawn.
// A limb's segments get thinner away from the body. Limbs are a little thinner than the balls at
// their joints, so the two surfaces never coincide (coinciding surfaces z-fight: dark saw-tooth
// bands where segments meet).
// Everything is in metres, y up; ``size`` (the body's height) scales every radius.
import * as THREE from 'three';
import { CONTACT_COLOUR } from 'minifilm-scene';

const UP = new THREE.Vector3(0, 1, 0);
// Radii as fractions of the body size (a 1.7 m person: torso 11 cm, thigh 6.8 cm, head 10.5 cm).
const RADIUS = { torso: 0.064, hips: 0.066, pelvis: 0.048, neck: 0.027, head: 0.062, leg: 0.040, arm: 0.027,
                 shoulder: 0.030 };
const TAPER = { leg: 0.8, arm: 0.86 };   // each segment down a limb is this much thinner than the last
const INSET = 0.82;                      // a limb's radius over its joints' balls: no coinciding surfaces
const SEGMENTS = 16;                     // around a limb and a ball alike

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
  const limb = new THREE.CylinderGeometry(1, 1, 1, SEGMENTS, 1, true);
  limb.translate(0, 0.5, 0);                  // spans y in [0, 1]: scaled to the bone, from the parent
  const ball = new THREE.SphereGeometry(1, SEGMENTS, 12);   // software WebGL pays for every triangle
  const blob = new THREE.PlaneGeometry(1, 1);
  blob.rotateX(-Math.PI / 2);                 // lies on the floor
  const shadowMap = shadowTexture();
  const contactMaterial = new THREE.MeshStandardMaterial({ color: CONTACT_COLOUR, roughness: 0.5 });

  function build(group, parents, colour, plan = null) {
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
    const hasPlan = !!(plan && Array.isArray(plan.parts) && plan.parts.length === parents.length);
    return { parents, plan: hasPlan ? plan : null, children, limbs, balls, head, nose, shadow, all, toes: [], joint,
             contactMaterial, shaped: false, ballRadius: [], headJoint: -1, neckJoint: -1, visible: true, size };
  }

  return { build };
}

// Each bone's radius from the body plan's parts (see the top of this file).
function shape(body) {
  const { parents, children, plan } = body, J = parents.length, s = body.size;
  const radius = new Array(J).fill(0);         // of the bone ending at joint j
  const depth = new Array(J).fill(0);          // segments below the first of its limb
  for (let j = 0; j < J; j++) {
    const part = plan.parts[j], p = parents[j];
    if (p >= 0 && (part === 'arm' || part === 'leg') && plan.parts[p] === part) depth[j] = depth[p] + 1;
    if (part === 'torso') radius[j] = RADIUS.torso * s;
    else if (part === 'neck') radius[j] = RADIUS.neck * s;
    else if (part === 'collar') radius[j] = RADIUS.shoulder * s;
    else if (part === 'arm') radius[j] = RADIUS.arm * s * TAPER.arm ** depth[j];
    else if (part === 'pelvis') radius[j] = RADIUS.pelvis * s;
    else if (part === 'leg') radius[j] = RADIUS.leg * s * TAPER.leg ** depth[j];
  }
  for (const l of body.limbs) l.r = INSET * radius[l.j];
  // a ball at every joint of the body as thick as the thickest bone there: the limbs' rounded ends
  const inBody = j => plan.parts[j] !== null && plan.parts[j] !== 'inhead';
  body.ballRadius = Array.from({ length: J }, (_, j) =>
    (inBody(j) ? Math.max(radius[j], ...children[j].filter(inBody).map(c => radius[c]), 0.012 * s) : 0));
  const hips = plan.parts.indexOf('hips');
  if (hips >= 0) body.ballRadius[hips] = Math.max(body.ballRadius[hips], RADIUS.hips * s);
  body.headJoint = plan.head;
  body.neckJoint = plan.neck;
  body.ballRadius[body.headJoint] = RADIUS.neck * s;
  body.toes = plan.toes.filter(t => parents[t] >= 0);
  body.shaped = true;
}

const tmp = new THREE.Vector3(), centre = new THREE.Vector3(), facing = new THREE.Vector3();

export function setMannequinVisible(body, on) {
  body.visible = on;
  for (const m of body.all) m.visible = on && body.shaped;   // no plan: never shaped, never shown
}

export function poseMannequin(body, sk, contacts = []) {
  const P = sk.joints.map(m => m.position);
  if (!body.plan) return;                     // not a humanoid: the sticks stay
  if (!body.shaped) { shape(body); setMannequinVisible(body, body.visible); }
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
