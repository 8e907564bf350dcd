// deepfoids replay viewer. Everything it needs is in this page: the recording
// (JSON header + gzipped sections, see replay/src/encode.rs) and three.js
// (gzipped module files from the npm package, see replay/src/html.rs).
//
// Order of work: load the library, decode the recording, build the scene
// (cage, fish as one instanced mesh, markers), wire the controls, then one
// requestAnimationFrame loop that advances the clock, interpolates every fish
// between the two frames around the current time, and draws the view and the
// P/M cursor.

// Import specifiers rewritten to blob URLs (checked against the vendored files by a Rust test).
const CORE_SPECIFIER = "'./three.core.js'";
const THREE_SPECIFIER = "'three'";

const $ = (id) => document.getElementById(id);
const statusBox = $('status');

// What a test (or a curious user in the console) can read and drive.
const api = (window.deepfoidsReplay = {
  ready: false,
  framesDrawn: 0,
  time: 0,
  frame: 0,
  playing: true,
  fps: 0,
  updateMs: 0,
  cursorX: null,
  selected: null,
  view: 'free',
  error: null,
});

function fail(err) {
  api.error = String(err && err.message ? err.message : err);
  statusBox.textContent = 'Cannot show this replay: ' + api.error;
  statusBox.classList.add('error');
  statusBox.hidden = false;
  console.error(err);
}

function base64Bytes(id) {
  const text = $(id).textContent.trim();
  const bin = atob(text);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

async function gunzip(id) {
  const stream = new Blob([base64Bytes(id)]).stream().pipeThrough(new DecompressionStream('gzip'));
  return new Response(stream).arrayBuffer();
}

async function gunzipText(id) {
  return new TextDecoder().decode(await gunzip(id));
}

function moduleUrl(text) {
  return URL.createObjectURL(new Blob([text], { type: 'text/javascript' }));
}

async function loadThree() {
  const coreUrl = moduleUrl(await gunzipText('lib-three-core'));
  const moduleText = (await gunzipText('lib-three-module')).replaceAll(CORE_SPECIFIER, JSON.stringify(coreUrl));
  const threeUrl = moduleUrl(moduleText);
  const orbitText = (await gunzipText('lib-orbit-controls')).replace('from ' + THREE_SPECIFIER, 'from ' + JSON.stringify(threeUrl));
  const THREE = await import(threeUrl);
  const { OrbitControls } = await import(moduleUrl(orbitText));
  return { THREE, OrbitControls };
}

const TYPES = { u8: Uint8Array, u16: Uint16Array, i16: Int16Array, u32: Uint32Array, f32: Float32Array };

async function loadRecording() {
  const meta = JSON.parse($('replay-meta').textContent);
  if (meta.format !== 1) throw new Error(`recording format ${meta.format}; this viewer reads format 1`);
  const packed = new Uint8Array(await gunzip('replay-data'));
  const s = {};
  for (const sec of meta.sections) {
    // Multi-byte sections are stored as byte planes: interleave them back.
    const T = TYPES[sec.type];
    const size = T.BYTES_PER_ELEMENT, n = sec.length;
    const bytes = new Uint8Array(n * size);
    for (let j = 0; j < size; j++) {
      const plane = packed.subarray(sec.offset + j * n, sec.offset + (j + 1) * n);
      for (let i = 0; i < n; i++) bytes[i * size + j] = plane[i];
    }
    s[sec.name] = new T(bytes.buffer, 0, n);
  }
  // Positions are stored as differences to the previous frame; add them up (wrapping like u16).
  const pos = s.position_delta;
  const row = 3 * meta.fish;
  for (let k = row; k < pos.length; k++) pos[k] = pos[k] + pos[k - row];
  s.position = pos;
  // Where each frame's chase pairs start.
  s.chase_start = new Uint32Array(meta.frames + 1);
  for (let f = 0; f < meta.frames; f++) s.chase_start[f + 1] = s.chase_start[f] + s.chase_count[f];
  return { meta, s };
}

function halfToFloat(h) {
  const sign = h & 0x8000 ? -1 : 1;
  const exp = (h >> 10) & 0x1f;
  const frac = h & 0x3ff;
  if (exp === 0) return sign * Math.pow(2, -14) * (frac / 1024);
  if (exp === 31) return frac ? NaN : sign * Infinity;
  return sign * Math.pow(2, exp - 15) * (1 + frac / 1024);
}

const STATE_NAMES = ['swarm', 'polarised', 'milling', 'transitional'];
const STATE_COLOURS = ['#b0b7bf', '#7fb2e5', '#f19c99', '#f3d37a'];

function fishGeometry(THREE) {
  // A laterally compressed spindle one body length long (+z = head), and a
  // two-sided tail fin: 98 triangles on 66 shared vertices, so 1,000 fish stay
  // cheap even on a software renderer.
  const profile = [
    [0.0, -0.4], [0.045, -0.3], [0.088, -0.12], [0.102, 0.06], [0.085, 0.28], [0.045, 0.43], [0.0, 0.5],
  ].map(([r, y]) => new THREE.Vector2(r, y));
  const body = new THREE.LatheGeometry(profile, 8);
  body.rotateX(Math.PI / 2); // lathe axis y → z, head towards +z
  body.scale(0.6, 1.0, 1.0); // narrower than deep
  const pos = Array.from(body.getAttribute('position').array);
  const index = Array.from(body.getIndex().array);
  const v = pos.length / 3;
  pos.push(0, 0, -0.36, 0, 0.11, -0.5, 0, -0.11, -0.5);
  index.push(v, v + 1, v + 2, v, v + 2, v + 1);
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
  g.setIndex(index);
  g.computeVertexNormals();
  return g;
}

/** Whether WebGL runs on a software rasteriser (SwiftShader, llvmpipe): there
 * multisampling costs 2–3× the frame time, so it is left off. */
function softwareGL() {
  try {
    const gl = document.createElement('canvas').getContext('webgl2');
    const ext = gl && gl.getExtension('WEBGL_debug_renderer_info');
    const name = ext ? String(gl.getParameter(ext.UNMASKED_RENDERER_WEBGL)) : '';
    gl?.getExtension('WEBGL_lose_context')?.loseContext();
    return /swiftshader|llvmpipe|software/i.test(name);
  } catch {
    return false;
  }
}

function buildCage(THREE, meta) {
  const group = new THREE.Group();
  const H = meta.cage.height;
  const outline = meta.cage.outline;
  const net = new THREE.LineBasicMaterial({ color: 0x9cc3df, transparent: true, opacity: 0.28 });
  const frame = new THREE.LineBasicMaterial({ color: 0xd9ecfa, transparent: true, opacity: 0.85 });
  const wallMat = new THREE.MeshBasicMaterial({ color: 0x3f6f95, transparent: true, opacity: 0.07, side: THREE.DoubleSide, depthWrite: false });
  const mesh = 0.5; // net line spacing (m)
  const netLines = [];
  const frameLines = [];
  const n = outline.length;
  for (let k = 0; k < n; k++) {
    const [x0, z0] = outline[k];
    const [x1, z1] = outline[(k + 1) % n];
    const len = Math.hypot(x1 - x0, z1 - z0);
    // Wall quad.
    const wall = new THREE.BufferGeometry();
    wall.setAttribute('position', new THREE.Float32BufferAttribute([
      x0, 0, z0, x1, 0, z1, x1, -H, z1, x0, 0, z0, x1, -H, z1, x0, -H, z0,
    ], 3));
    group.add(new THREE.Mesh(wall, wallMat));
    // Net: vertical and horizontal lines.
    const cols = Math.max(1, Math.round(len / mesh));
    for (let c = 1; c < cols; c++) {
      const u = c / cols;
      const x = x0 + (x1 - x0) * u, z = z0 + (z1 - z0) * u;
      netLines.push(x, 0, z, x, -H, z);
    }
    const rows = Math.max(1, Math.round(H / mesh));
    for (let r = 1; r < rows; r++) {
      const y = -H * r / rows;
      netLines.push(x0, y, z0, x1, y, z1);
    }
    frameLines.push(x0, 0, z0, x1, 0, z1, x0, -H, z0, x1, -H, z1, x0, 0, z0, x0, -H, z0);
  }
  // Bottom net: a grid clipped to the outline's bounding box, kept inside by the convex outline test.
  const xs = outline.map((p) => p[0]), zs = outline.map((p) => p[1]);
  const inside = (x, z) => {
    for (let k = 0; k < n; k++) {
      const [ax, az] = outline[k];
      const [bx, bz] = outline[(k + 1) % n];
      if ((bx - ax) * (z - az) - (bz - az) * (x - ax) < -1e-6) return false;
    }
    return true;
  };
  const clipSegment = (a, b) => {
    // Bisection to the outline from each end (the outline is convex).
    const steps = 200;
    let first = null, last = null;
    for (let i = 0; i <= steps; i++) {
      const u = i / steps;
      const x = a[0] + (b[0] - a[0]) * u, z = a[1] + (b[1] - a[1]) * u;
      if (inside(x, z)) { if (!first) first = [x, z]; last = [x, z]; }
    }
    return first ? [first, last] : null;
  };
  for (let x = Math.ceil(Math.min(...xs) / mesh) * mesh; x < Math.max(...xs); x += mesh) {
    const s = clipSegment([x, Math.min(...zs)], [x, Math.max(...zs)]);
    if (s) netLines.push(s[0][0], -H, s[0][1], s[1][0], -H, s[1][1]);
  }
  for (let z = Math.ceil(Math.min(...zs) / mesh) * mesh; z < Math.max(...zs); z += mesh) {
    const s = clipSegment([Math.min(...xs), z], [Math.max(...xs), z]);
    if (s) netLines.push(s[0][0], -H, s[0][1], s[1][0], -H, s[1][1]);
  }
  const lines = (arr, mat) => {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(arr, 3));
    return new THREE.LineSegments(g, mat);
  };
  group.add(lines(netLines, net));
  group.add(lines(frameLines, frame));
  // Water surface and bottom as filled polygons.
  const shape = new THREE.Shape(outline.map(([x, z]) => new THREE.Vector2(x, -z)));
  const surface = new THREE.Mesh(new THREE.ShapeGeometry(shape),
    new THREE.MeshBasicMaterial({ color: 0x8fd3ff, transparent: true, opacity: 0.12, side: THREE.DoubleSide, depthWrite: false }));
  surface.rotation.x = -Math.PI / 2;
  group.add(surface);
  const bottom = new THREE.Mesh(new THREE.ShapeGeometry(shape),
    new THREE.MeshBasicMaterial({ color: 0x1d3346, transparent: true, opacity: 0.55, side: THREE.DoubleSide, depthWrite: false }));
  bottom.rotation.x = -Math.PI / 2;
  bottom.position.y = -H - 0.002;
  group.add(bottom);
  // Obstacles.
  const obstacleMat = new THREE.MeshLambertMaterial({ color: 0x8a7a66 });
  for (const o of meta.obstacles) {
    if (o.kind === 'sphere') {
      const m = new THREE.Mesh(new THREE.SphereGeometry(o.radius, 24, 16), obstacleMat);
      m.position.set(...o.center);
      group.add(m);
    } else if (o.kind === 'cylinder') {
      const h = o.y_max - o.y_min;
      const m = new THREE.Mesh(new THREE.CylinderGeometry(o.radius, o.radius, h, 24), obstacleMat);
      m.position.set(o.x, (o.y_max + o.y_min) / 2, o.z);
      group.add(m);
    }
  }
  return group;
}

/** Text made safe for innerHTML. */
function esc(text) {
  return String(text).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]);
}

function fmt(x, digits) {
  return Number.isFinite(x) ? x.toFixed(digits) : '–';
}

async function main() {
  const [{ THREE, OrbitControls }, { meta, s }] = await Promise.all([loadThree(), loadRecording()]);
  const N = meta.fish, F = meta.frames;
  const times = s.times;
  const t0 = times[0], t1 = times[F - 1];
  const q = meta.quant;
  const H = meta.cage.height;
  const radius = Math.max(...meta.cage.outline.map(([x, z]) => Math.hypot(x, z)));

  // Title and legend.
  const info = meta.info;
  $('subtitle').textContent = [
    info.description, `policy ${info.policy}`, `seed ${info.seed}`, info.phase, meta.cage.describe,
    `${N} fish`, `${F} frames, ${fmt(t1 - t0, 1)} s`, info.source, ...info.notes,
  ].filter(Boolean).join(' · ');
  $('about-source').textContent = `${info.title}. ${info.source}. ${info.notes.join(' ')}`;
  const legend = $('legend');
  for (const b of meta.behaviours) {
    const r = document.createElement('div');
    r.className = 'row';
    r.innerHTML = `<span class="swatch" style="background:${esc(b.colour)}"></span>`;
    r.append(`${b.name} (${b.count})`);
    legend.append(r);
  }
  const nDominant = s.dominant.reduce((a, d) => a + d, 0);
  const extra = document.createElement('div');
  extra.innerHTML = `<div class="row"><span class="dot"></span>dominant fish (${nDominant})</div>` +
    (meta.has_chases ? '<div class="row"><span class="line"></span>chase: both fish red, joined by a line</div>' : '<div class="row hint">chases not recorded</div>') +
    '<div class="hint">click a fish to follow it</div>';
  legend.append(extra);

  // Renderer, scene, camera.
  const canvas = $('view');
  const software = softwareGL();
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: !software });
  api.softwareGL = software;
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x0b2236);
  scene.fog = new THREE.Fog(0x0b2236, radius * 2.5, radius * 7);
  scene.add(new THREE.HemisphereLight(0xdcefff, 0x2a3a44, 2.4));
  const sun = new THREE.DirectionalLight(0xffffff, 2.0);
  sun.position.set(0.3, 1, 0.2);
  scene.add(sun);
  scene.add(buildCage(THREE, meta));
  const camera = new THREE.PerspectiveCamera(40, 1, 0.05, radius * 20);
  const controls = new OrbitControls(camera, canvas);
  controls.enableDamping = true;
  controls.dampingFactor = 0.12;
  const centre = new THREE.Vector3(0, -H / 2, 0);

  // Fish: one instanced mesh, per-instance colour by behaviour.
  const geometry = fishGeometry(THREE);
  const material = new THREE.MeshLambertMaterial();
  const fish = new THREE.InstancedMesh(geometry, material, N);
  fish.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
  fish.frustumCulled = false; // instances move; the mesh's bounds are recomputed only for picking
  const colour = new THREE.Color();
  const behaviourColours = meta.behaviours.map((b) => new THREE.Color(b.colour));
  for (let i = 0; i < N; i++) {
    colour.copy(behaviourColours[s.behaviour[i]]);
    fish.setColorAt(i, colour);
  }
  scene.add(fish);
  // Dominant fish: a white dot on the back. Chases: red segments aggressor → target.
  const dominantIdx = [];
  for (let i = 0; i < N; i++) if (s.dominant[i]) dominantIdx.push(i);
  const dotGeom = new THREE.BufferGeometry();
  const dotPos = new Float32Array(Math.max(1, dominantIdx.length) * 3);
  dotGeom.setAttribute('position', new THREE.BufferAttribute(dotPos, 3).setUsage(THREE.DynamicDrawUsage));
  dotGeom.setDrawRange(0, dominantIdx.length);
  const dots = new THREE.Points(dotGeom, new THREE.PointsMaterial({ color: 0xffffff, size: 4, sizeAttenuation: false, depthTest: false, transparent: true }));
  dots.frustumCulled = false;
  dots.renderOrder = 2;
  scene.add(dots);
  let maxPairs = 0;
  for (let f = 0; f < F; f++) maxPairs = Math.max(maxPairs, s.chase_count[f]);
  const chaseGeom = new THREE.BufferGeometry();
  const chasePos = new Float32Array(Math.max(1, maxPairs) * 6);
  chaseGeom.setAttribute('position', new THREE.BufferAttribute(chasePos, 3).setUsage(THREE.DynamicDrawUsage));
  const chaseColour = new THREE.Color(0xff3b30);
  let tinted = new Set();
  const chaseLines = new THREE.LineSegments(chaseGeom, new THREE.LineBasicMaterial({ color: 0xff3b30, depthTest: false, transparent: true }));
  chaseLines.frustumCulled = false;
  chaseLines.renderOrder = 3;
  scene.add(chaseLines);
  // The followed fish: a yellow wireframe copy around it.
  const halo = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({ color: 0xffe14d, wireframe: true }));
  halo.visible = false;
  scene.add(halo);

  // Per-frame state of every fish (interpolated), reused every frame.
  const P = new Float32Array(3 * N); // position
  const D = new Float32Array(3 * N); // heading
  const frameAt = (t) => {
    let lo = 0, hi = F - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (times[mid] <= t) lo = mid; else hi = mid - 1;
    }
    return lo;
  };
  const head = (k, out, o) => {
    const yaw = (s.yaw[k] / q.yaw_steps) * 2 * Math.PI - Math.PI;
    const pitch = (s.pitch[k] / q.pitch_steps) * (Math.PI / 2);
    const c = Math.cos(pitch);
    out[o] = c * Math.sin(yaw); out[o + 1] = Math.sin(pitch); out[o + 2] = c * Math.cos(yaw);
  };
  const hA = new Float32Array(3), hB = new Float32Array(3);
  const respawned = meta.flag_bits.respawned;
  function pose(t) {
    const f = frameAt(t);
    const g = Math.min(f + 1, F - 1);
    const span = times[g] - times[f];
    const a = span > 0 ? Math.min(1, Math.max(0, (t - times[f]) / span)) : 0;
    const m = matrixArray;
    for (let i = 0; i < N; i++) {
      const kf = f * N + i, kg = g * N + i;
      // A respawn between the frames is a jump: hold the old pose, then snap.
      const w = (s.flags[kg] & respawned) ? (a >= 1 ? 1 : 0) : a;
      for (let ax = 0; ax < 3; ax++) {
        const qa = s.position[3 * kf + ax], qb = s.position[3 * kg + ax];
        P[3 * i + ax] = q.origin[ax] + (qa + (qb - qa) * w) * q.step;
      }
      head(kf, hA, 0);
      head(kg, hB, 0);
      let dx = hA[0] + (hB[0] - hA[0]) * w, dy = hA[1] + (hB[1] - hA[1]) * w, dz = hA[2] + (hB[2] - hA[2]) * w;
      let l = Math.hypot(dx, dy, dz);
      if (l < 1e-6) { dx = hB[0]; dy = hB[1]; dz = hB[2]; l = 1; }
      dx /= l; dy /= l; dz /= l;
      D[3 * i] = dx; D[3 * i + 1] = dy; D[3 * i + 2] = dz;
      // Basis: z = heading, x = up × z (level wings), y = z × x; scaled by the body length.
      let xx = dz, xz = -dx; // up × d with up = (0, 1, 0)
      let xl = Math.hypot(xx, xz);
      if (xl < 1e-4) { xx = 1; xz = 0; xl = 1; }
      xx /= xl; xz /= xl;
      const yx = dy * xz, yy = dz * xx - dx * xz, yz = -dy * xx;
      const bl = s.bl[i];
      const o = 16 * i;
      m[o] = xx * bl; m[o + 1] = 0; m[o + 2] = xz * bl; m[o + 3] = 0;
      m[o + 4] = yx * bl; m[o + 5] = yy * bl; m[o + 6] = yz * bl; m[o + 7] = 0;
      m[o + 8] = dx * bl; m[o + 9] = dy * bl; m[o + 10] = dz * bl; m[o + 11] = 0;
      m[o + 12] = P[3 * i]; m[o + 13] = P[3 * i + 1]; m[o + 14] = P[3 * i + 2]; m[o + 15] = 1;
    }
    fish.instanceMatrix.needsUpdate = true;
    for (let j = 0; j < dominantIdx.length; j++) {
      const i = dominantIdx[j];
      const lift = 0.12 * s.bl[i];
      dotPos[3 * j] = P[3 * i]; dotPos[3 * j + 1] = P[3 * i + 1] + lift; dotPos[3 * j + 2] = P[3 * i + 2];
    }
    dotGeom.attributes.position.needsUpdate = true;
    const near = a < 0.5 ? f : g;
    const c0 = s.chase_start[near], c1 = s.chase_start[near + 1];
    const chasing = new Set();
    for (let k = c0; k < c1; k++) {
      const ag = s.chase_pairs[2 * k], tg = s.chase_pairs[2 * k + 1];
      const o = 6 * (k - c0);
      chasePos.set([P[3 * ag], P[3 * ag + 1], P[3 * ag + 2], P[3 * tg], P[3 * tg + 1], P[3 * tg + 2]], o);
      chasing.add(ag);
      chasing.add(tg);
    }
    chaseGeom.setDrawRange(0, 2 * (c1 - c0));
    chaseGeom.attributes.position.needsUpdate = true;
    // Fish in a chase turn red; the others keep their behaviour's colour.
    let recoloured = false;
    for (const i of tinted) {
      if (!chasing.has(i)) { fish.setColorAt(i, behaviourColours[s.behaviour[i]]); recoloured = true; }
    }
    for (const i of chasing) {
      if (!tinted.has(i)) { fish.setColorAt(i, chaseColour); recoloured = true; }
    }
    tinted = chasing;
    if (recoloured) fish.instanceColor.needsUpdate = true;
    return { f, near };
  }
  const matrixArray = fish.instanceMatrix.array;

  // Views.
  function setView(v) {
    api.view = v;
    const R = radius * 1.06;
    const th = Math.tan((camera.fov * Math.PI) / 360);
    controls.target.copy(centre);
    if (v === 'top') {
      // Straight down, +x to the right and +z down the screen (as the GIF's top view).
      const d = (R / (th * Math.min(1, camera.aspect))) * 1.04;
      camera.position.set(0, d, 0.0001);
    } else if (v === 'side') {
      // From +z, level: +x to the right, up is up (as the GIF's side view).
      const d = Math.max(R / (th * camera.aspect), H / 2 / th) * 1.08;
      camera.position.set(0, centre.y, R + d);
    } else {
      const d = (R / th) * 1.25;
      camera.position.set(d * 0.62, centre.y + d * 0.5, d * 0.62);
    }
    camera.lookAt(controls.target);
    controls.update();
    for (const b of document.querySelectorAll('#views button')) b.classList.toggle('active', b.dataset.view === v);
    if (api.selected !== null) followOffset = camera.position.clone().sub(controls.target);
  }

  // Following a fish.
  let followOffset = null;
  const selectFish = (i) => {
    api.selected = i;
    halo.visible = i !== null;
    $('fish-info').hidden = i === null;
    followOffset = i === null ? null : camera.position.clone().sub(controls.target);
    if (i === null) { controls.target.copy(centre); controls.update(); }
  };
  const termNames = meta.term_names;
  function showFish(i, f) {
    const k = f * N + i;
    const bl = s.bl[i];
    const b = meta.behaviours[s.behaviour[i]];
    const speed = s.speed[k] / 1000;
    const depth = -P[3 * i + 1];
    const flags = s.flags[k];
    let role = 'not in a chase';
    if (!meta.has_chases) role = 'chases not recorded';
    else if (flags & meta.flag_bits.chasing) role = 'chasing';
    else if (flags & meta.flag_bits.chased) role = 'being chased';
    let rows = `<tr><td>speed</td><td class="v">${fmt(speed, 2)} m/s</td><td class="v">${fmt(speed / bl, 2)} BL/s</td></tr>` +
      `<tr><td>depth</td><td class="v">${fmt(depth, 2)} m</td><td class="v muted">of ${fmt(H, 1)} m</td></tr>` +
      `<tr><td>role</td><td class="v" colspan="2">${role}</td></tr>`;
    if (meta.has_terms) {
      let total = 0;
      rows += '<tr><td colspan="3" class="muted">reward terms of its latest decision</td></tr>';
      for (let t = 0; t < termNames.length; t++) {
        const v = halfToFloat(s.terms[(t * F + f) * N + i]); // stored [term][frame][fish]
        total += v;
        const cls = v < 0 ? 'neg' : v > 0 ? 'pos' : 'muted';
        rows += `<tr><td>${esc(termNames[t])}</td><td class="v ${cls}" colspan="2">${fmt(v, 3)}</td></tr>`;
      }
      rows += `<tr><td><b>total</b></td><td class="v" colspan="2"><b>${fmt(total, 3)}</b></td></tr>`;
    } else {
      rows += '<tr><td colspan="3" class="muted">reward terms not recorded by this source</td></tr>';
    }
    $('fish-info').innerHTML = `<h3>fish ${i}</h3><div class="muted">${esc(b.name)} · BL ${fmt(bl, 3)} m${s.dominant[i] ? ' · dominant' : ''}</div><table>${rows}</table>`;
  }

  // Picking: a click (not a drag) on the view.
  const raycaster = new THREE.Raycaster();
  const pointer = new THREE.Vector2();
  let down = null;
  canvas.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
  canvas.addEventListener('pointerup', (e) => {
    if (!down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
    const r = canvas.getBoundingClientRect();
    pointer.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
    raycaster.setFromCamera(pointer, camera);
    fish.computeBoundingSphere();
    const hit = raycaster.intersectObject(fish, false)[0];
    selectFish(hit ? hit.instanceId : null);
  });

  // Clock and controls.
  let time = t0;
  let speed = 1;
  let playing = true;
  const playButton = $('play');
  const scrub = $('scrub');
  const setPlaying = (p) => {
    playing = p;
    api.playing = p;
    playButton.textContent = p ? 'Pause' : 'Play';
  };
  const seek = (t) => { time = Math.min(t1, Math.max(t0, t)); };
  playButton.addEventListener('click', () => setPlaying(!playing));
  let scrubbing = false;
  scrub.addEventListener('input', () => { seek(t0 + (scrub.value / 10000) * (t1 - t0)); });
  scrub.addEventListener('pointerdown', () => { scrubbing = true; });
  window.addEventListener('pointerup', () => { scrubbing = false; });
  $('speed').addEventListener('change', (e) => { speed = Number(e.target.value); });
  for (const b of document.querySelectorAll('#views button')) b.addEventListener('click', () => setView(b.dataset.view));
  $('about-button').addEventListener('click', () => { $('about').hidden = !$('about').hidden; });
  $('about-close').addEventListener('click', () => { $('about').hidden = true; });
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' && e.target.type !== 'range') return;
    const frameStep = F > 1 ? (t1 - t0) / (F - 1) : 0;
    if (e.key === ' ') { setPlaying(!playing); e.preventDefault(); }
    else if (e.key === 'ArrowRight') { setPlaying(false); seek(times[Math.min(F - 1, frameAt(time + 1e-4) + 1)] ?? time + frameStep); e.preventDefault(); }
    else if (e.key === 'ArrowLeft') { setPlaying(false); seek(times[Math.max(0, frameAt(time - 1e-4))]); e.preventDefault(); }
    else if (e.key === 't' || e.key === 'T') setView('top');
    else if (e.key === 's' || e.key === 'S') setView('side');
    else if (e.key === 'f' || e.key === 'F') setView('free');
    else if (e.key === 'Escape') { selectFish(null); $('about').hidden = true; }
  });

  // P/M chart.
  const chart = $('chart');
  const ctx = chart.getContext('2d');
  const pad = { l: 44, r: 12, t: 10, b: 24 };
  let chartBase = null;
  function drawChartBase() {
    const dpr = window.devicePixelRatio || 1;
    const w = chart.clientWidth, h = chart.clientHeight;
    chart.width = Math.round(w * dpr);
    chart.height = Math.round(h * dpr);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = '#f7f9fb';
    ctx.fillRect(0, 0, w, h);
    const ct = s.curve_t, cp = s.curve_p, cm = s.curve_m, cs = s.curve_state;
    const x = (t) => pad.l + ((t - t0) / Math.max(1e-9, t1 - t0)) * (w - pad.l - pad.r);
    const y = (v) => pad.t + (1 - v / 1.02) * (h - pad.t - pad.b);
    // State band along the bottom of the plot.
    for (let k = 0; k < ct.length; k++) {
      const xa = x(ct[k]), xb = k + 1 < ct.length ? x(ct[k + 1]) : x(ct[k]) + 1;
      ctx.fillStyle = STATE_COLOURS[cs[k]];
      ctx.fillRect(xa, h - pad.b - 6, Math.max(1, xb - xa), 6);
    }
    ctx.strokeStyle = '#c9d2db';
    ctx.lineWidth = 1;
    ctx.font = '11px system-ui, sans-serif';
    ctx.fillStyle = '#4a5a6a';
    for (const v of [0, 0.35, 0.65, 1]) {
      ctx.setLineDash(v === 0.35 || v === 0.65 ? [5, 4] : []);
      ctx.beginPath(); ctx.moveTo(pad.l, y(v)); ctx.lineTo(w - pad.r, y(v)); ctx.stroke();
      ctx.fillText(v.toFixed(2), 8, y(v) + 4);
    }
    ctx.setLineDash([]);
    // Time ticks at a round step (1, 2 or 5 × 10^k s), about 80 px apart.
    const raw = ((t1 - t0) * 80) / Math.max(1, w - pad.l - pad.r);
    const mag = Math.pow(10, Math.floor(Math.log10(Math.max(raw, 1e-6))));
    const step = [1, 2, 5, 10].map((m) => m * mag).find((v) => v >= raw);
    for (let t = Math.ceil(t0 / step) * step; t <= t1 + 1e-9; t += step) {
      ctx.fillText(`${+t.toFixed(6)} s`, x(t) - 10, h - 6);
    }
    const line = (vals, col) => {
      ctx.strokeStyle = col; ctx.lineWidth = 1.6; ctx.beginPath();
      for (let k = 0; k < ct.length; k++) { const px = x(ct[k]), py = y(vals[k]); k ? ctx.lineTo(px, py) : ctx.moveTo(px, py); }
      ctx.stroke();
    };
    line(cp, '#1f77b4');
    line(cm, '#d62728');
    ctx.fillStyle = '#1f77b4'; ctx.fillText('P polarisation', w - pad.r - 190, pad.t + 10);
    ctx.fillStyle = '#d62728'; ctx.fillText('M milling', w - pad.r - 95, pad.t + 10);
    ctx.fillStyle = '#4a5a6a';
    let legendX = pad.l + 6;
    for (let k = 0; k < 4; k++) {
      ctx.fillStyle = STATE_COLOURS[k]; ctx.fillRect(legendX, pad.t + 2, 10, 8);
      ctx.fillStyle = '#4a5a6a'; ctx.fillText(STATE_NAMES[k], legendX + 13, pad.t + 10);
      legendX += 22 + ctx.measureText(STATE_NAMES[k]).width;
    }
    chartBase = { image: ctx.getImageData(0, 0, chart.width, chart.height), x, w, h };
  }
  function drawCursor(t) {
    if (!chartBase) return;
    ctx.putImageData(chartBase.image, 0, 0);
    const px = chartBase.x(t);
    ctx.strokeStyle = '#111';
    ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(px, pad.t); ctx.lineTo(px, chartBase.h - pad.b); ctx.stroke();
    // The values at the cursor.
    const ct = s.curve_t;
    let k = 0, hi = ct.length - 1;
    while (k < hi) { const mid = (k + hi + 1) >> 1; if (ct[mid] <= t) k = mid; else hi = mid - 1; }
    ctx.fillStyle = '#111';
    ctx.font = '11px system-ui, sans-serif';
    const label = `P ${fmt(s.curve_p[k], 2)}  M ${fmt(s.curve_m[k], 2)}  ${STATE_NAMES[s.curve_state[k]] ?? ''}`;
    const lx = px + 6 + 150 > chartBase.w ? px - 156 : px + 6;
    ctx.fillText(label, lx, chartBase.h - pad.b - 10);
    api.cursorX = px;
  }
  const seekFromChart = (e) => {
    const r = chart.getBoundingClientRect();
    const u = (e.clientX - r.left - pad.l) / (r.width - pad.l - pad.r);
    seek(t0 + u * (t1 - t0));
  };
  let chartDrag = false;
  chart.addEventListener('pointerdown', (e) => { chartDrag = true; seekFromChart(e); });
  window.addEventListener('pointermove', (e) => { if (chartDrag) seekFromChart(e); });
  window.addEventListener('pointerup', () => { chartDrag = false; });

  // Size.
  function resize() {
    const w = canvas.clientWidth, h = canvas.clientHeight;
    if (w === 0 || h === 0) return;
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    drawChartBase();
  }
  new ResizeObserver(resize).observe($('stage'));
  new ResizeObserver(() => drawChartBase()).observe(chart);
  resize();

  // Start as the address says: #t=12.5&view=top&fish=7&speed=2&paused
  const params = new URLSearchParams(location.hash.slice(1));
  setView(['top', 'side', 'free'].includes(params.get('view')) ? params.get('view') : 'free');
  if (params.has('t')) seek(Number(params.get('t')) || t0);
  if (params.has('speed')) { speed = Number(params.get('speed')) || 1; $('speed').value = String(speed); }
  if (params.has('paused')) setPlaying(false);
  api.seek = seek;
  api.play = () => setPlaying(true);
  api.pause = () => setPlaying(false);
  api.setView = setView;
  api.select = (i) => selectFish(i === null ? null : Math.max(0, Math.min(N - 1, i | 0)));
  api.fishPosition = (i) => [P[3 * i], P[3 * i + 1], P[3 * i + 2]];
  // Where fish i is drawn, in page pixels (for clicking it from a test).
  api.screenOf = (i) => {
    const v = new THREE.Vector3(P[3 * i], P[3 * i + 1], P[3 * i + 2]).project(camera);
    const r = canvas.getBoundingClientRect();
    return [r.left + ((v.x + 1) / 2) * r.width, r.top + ((1 - v.y) / 2) * r.height];
  };
  api.duration = t1 - t0;
  api.frames = F;
  api.fish = N;

  // The loop.
  let last = performance.now();
  let fpsCount = 0, fpsSince = last, updateSum = 0;
  const lastTarget = new THREE.Vector3();
  const haloScale = new THREE.Vector3(1.25, 1.25, 1.15);
  statusBox.hidden = true;
  if (params.has('fish')) selectFish(Math.max(0, Math.min(N - 1, Number(params.get('fish')) | 0)));
  function tick(now) {
    const dt = Math.min(0.25, (now - last) / 1000);
    last = now;
    if (playing) {
      time += dt * speed;
      if (time > t1) time = t0 + ((time - t0) % Math.max(1e-9, t1 - t0));
    }
    const u0 = performance.now();
    const { near } = pose(time);
    updateSum += performance.now() - u0;
    if (api.selected !== null) {
      const i = api.selected;
      lastTarget.set(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
      controls.target.copy(lastTarget);
      if (followOffset) camera.position.copy(lastTarget).add(followOffset);
      halo.matrix.fromArray(matrixArray, 16 * i);
      halo.matrix.scale(haloScale);
      halo.matrixAutoUpdate = false;
      halo.matrixWorldNeedsUpdate = true;
      showFish(i, near);
    }
    controls.update();
    if (api.selected !== null) followOffset = camera.position.clone().sub(controls.target);
    renderer.render(scene, camera);
    drawCursor(time);
    if (!scrubbing) scrub.value = String(Math.round(((time - t0) / Math.max(1e-9, t1 - t0)) * 10000));
    $('clock').textContent = `${fmt(time, 1)} / ${fmt(t1, 1)} s`;
    api.time = time;
    api.frame = near;
    api.framesDrawn++;
    fpsCount++;
    if (now - fpsSince >= 1000) {
      api.fps = (fpsCount * 1000) / (now - fpsSince);
      api.updateMs = updateSum / fpsCount;
      $('fps').textContent = `${api.fps.toFixed(0)} fps`;
      fpsCount = 0; updateSum = 0; fpsSince = now;
    }
    if (!api.ready) { api.ready = true; document.body.dataset.ready = '1'; }
    requestAnimationFrame(tick);
  }
  requestAnimationFrame(tick);
}

if (typeof DecompressionStream === 'undefined') {
  fail(new Error('this browser lacks DecompressionStream (any current Chrome, Edge, Firefox or Safari has it)'));
} else {
  main().catch(fail);
}
