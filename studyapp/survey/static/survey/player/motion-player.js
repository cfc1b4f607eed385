// <motion-player>: plays a motion payload (rendering/player.py) as a 3D figure in WebGL 2.
//
// The camera is the rendered clips': the payload carries the set's azimuth, elevation and
// field of view, and how the clip's video films each frame (rendering.framing.Framing.shot:
// the look-at, the eye's distance and the frame's window over a larger canvas, which keeps
// the figure inside the frame), so a clip is framed here as in its mp4. Every player of a page runs on one clock: they play, pause, seek
// and loop together. Each element fires `play`, `pause`, `seek` and one `ended` per
// completed loop (as a looping <video> would be counted), and `loadeddata` once its first
// frame is drawn. Pages check `supported()` first and keep the mp4 otherwise.

import * as THREE from '../vendor/three/three.module.js';

const MAGIC = 'MPLY';
const VERSION = 2;
const HEADER_BYTES = 52;
const ZOOM_STEPS = 2048; // rendering/player.py: the eye's distance, per the set's distance

// rendering/palette.py, sRGB; the renderer passes colours through unconverted.
const PALETTE = {
  left: [236, 112, 52], right: [46, 118, 214], centre: [132, 138, 150],
  skyTop: [250, 250, 251], skyHorizon: [229, 232, 237],
  floorLight: [222, 225, 230], floorDark: [206, 210, 217], shadow: [92, 98, 110],
  body: [168, 172, 182],
};
const BODY_TINT = 0.16; // rendering/styles/mesh.py: left and right lean this far to the palette
const SHADOW_OPACITY = 0.42;

THREE.ColorManagement.enabled = false;

const rgb = (c) => new THREE.Color(c[0] / 255, c[1] / 255, c[2] / 255);
const mix = (a, b, t) => a.map((v, k) => v + (b[k] - v) * t);

let webgl2 = null;

/** Return whether this browser can draw the player (WebGL 2); otherwise keep the mp4. */
export function supported() {
  if (webgl2 === null) {
    try {
      const canvas = document.createElement('canvas');
      webgl2 = Boolean(window.WebGL2RenderingContext && canvas.getContext('webgl2'));
    } catch (error) {
      webgl2 = false;
    }
  }
  return webgl2;
}

/** Parse a payload (ArrayBuffer) into typed arrays; throws on anything else. */
export function parsePayload(buffer) {
  const view = new DataView(buffer);
  const magic = String.fromCharCode(...new Uint8Array(buffer, 0, 4));
  if (buffer.byteLength < HEADER_BYTES || magic !== MAGIC) {
    throw new Error('not a motion payload');
  }
  const version = view.getUint16(4, true);
  if (version !== VERSION) {
    throw new Error(`motion payload version ${version}, this player reads ${VERSION}: rebuild the stimuli`);
  }
  const frames = view.getUint16(6, true);
  const joints = view.getUint16(8, true);
  const flags = view.getUint16(10, true);
  const f = (k) => view.getFloat32(12 + 4 * k, true);
  const header = {
    frames, joints, orthographic: Boolean(flags & 1), fps: f(0), step: f(1),
    azimuth: f(2), elevation: f(3), fov: f(4), distance: f(5), windowStep: f(6), height: f(7),
    shadowSlant: f(8), stickBone: f(9),
  };
  let at = HEADER_BYTES;
  const parents = new Int8Array(buffer, at, joints);
  const sides = new Int8Array(buffer, at + joints, joints);
  at += 2 * joints;
  const units = (offset) => Array.from({ length: joints }, (_, j) => view.getUint16(offset + 2 * j, true));
  const stickRadii = units(at).map((u) => u * header.step);
  const bodyRadii = units(at + 2 * joints).map((u) => u * header.step);
  at += 4 * joints;
  at += (4 - (at % 4)) % 4;
  if (at + 6 * frames * joints + 12 * frames !== buffer.byteLength) {
    throw new Error('payload size does not match its header');
  }
  const positions = new Int16Array(buffer, at, frames * joints * 3);
  at += 6 * frames * joints;
  const targets = new Int16Array(buffer, at, frames * 3); // look-at (x, y, z) in steps
  const windows = new Int16Array(buffer, at + 6 * frames, frames * 2); // in window steps
  const zooms = new Int16Array(buffer, at + 10 * frames, frames); // in ZOOM_STEPS
  return {
    ...header, parents: Array.from(parents), sides: Array.from(sides), stickRadii, bodyRadii,
    positions, targets, windows, zooms,
  };
}

// --- one clock for the page ---------------------------------------------------------

const players = new Set();
// `shown`: the time of the frame on screen while playing (null until one is drawn), so a
// pause freezes what the participant sees rather than a frame that was never drawn.
const clock = { origin: performance.now(), offset: 0, paused: true, hiddenPause: false, shown: null };

function now() {
  return clock.paused ? clock.offset : clock.offset + (performance.now() - clock.origin) / 1000;
}

function broadcast(type, detail) {
  for (const player of players) player.dispatchEvent(new CustomEvent(type, { detail: { ...detail, time: now() } }));
}

/** The page's shared clock: every player follows it. */
export const playback = {
  get time() { return now(); },
  get paused() { return clock.paused; },
  play(cause = 'api') {
    if (!clock.paused) return;
    clock.origin = performance.now();
    clock.paused = false;
    clock.shown = null;
    broadcast('play', { cause });
    wake();
  },
  pause(cause = 'api') {
    if (clock.paused) return;
    clock.offset = clock.shown ?? now();
    clock.paused = true;
    broadcast('pause', { cause });
  },
  seek(seconds, cause = 'api') {
    clock.offset = Math.max(0, seconds);
    clock.origin = performance.now();
    clock.shown = null;
    for (const player of players) player._seeked();
    broadcast('seek', { cause });
    wake();
  },
  replay(cause = 'api') {
    this.seek(0, cause);
    this.play(cause);
  },
};

document.addEventListener('visibilitychange', () => {
  // A hidden page is not watched: stop the clock, so no loop is counted unseen.
  if (document.hidden && !clock.paused) {
    clock.hiddenPause = true;
    playback.pause('hidden');
  } else if (!document.hidden && clock.hiddenPause) {
    clock.hiddenPause = false;
    playback.play('visible');
  }
});

// --- one renderer for every player --------------------------------------------------

let shared = null;

function renderer() {
  if (!shared) {
    const canvas = document.createElement('canvas');
    // No MSAA: the canvas is drawn at the device's pixel ratio, and software GL (phones
    // without a GPU driver, headless browsers) pays for every sample.
    const gl = new THREE.WebGLRenderer({ canvas, antialias: false, stencil: true, alpha: false });
    // A lost context (the GPU reset, too many contexts) draws nothing more: every player
    // says so with an `error`, so the page can go back to its videos.
    canvas.addEventListener('webglcontextlost', () => {
      for (const player of players) {
        player.dispatchEvent(new CustomEvent('error', { detail: { message: 'WebGL context lost', contextLost: true, time: now() } }));
      }
    });
    gl.outputColorSpace = THREE.LinearSRGBColorSpace;
    gl.setPixelRatio(1);
    shared = gl;
  }
  return shared;
}

let ticking = false;

function wake() {
  if (!ticking) {
    ticking = true;
    requestAnimationFrame(tick);
  }
}

function tick() {
  ticking = false;
  let busy = false;
  const time = now(); // one reading for every player: the same frame everywhere
  for (const player of players) busy = player._draw(time) || busy;
  if (!clock.paused) clock.shown = time;
  if (busy || !clock.paused) wake();
}

// --- scenery ------------------------------------------------------------------------

function skyTexture() {
  const canvas = document.createElement('canvas');
  canvas.width = 1;
  canvas.height = 256;
  const context = canvas.getContext('2d');
  const gradient = context.createLinearGradient(0, 0, 0, 256);
  gradient.addColorStop(0, `rgb(${PALETTE.skyTop})`);
  gradient.addColorStop(1, `rgb(${PALETTE.skyHorizon})`);
  context.fillStyle = gradient;
  context.fillRect(0, 0, 1, 256);
  const texture = new THREE.CanvasTexture(canvas);
  texture.colorSpace = THREE.NoColorSpace;
  return texture;
}

const FLOOR_VERTEX = `
varying vec2 world;
void main() {
  vec4 place = modelMatrix * vec4(position, 1.0);
  world = place.xy;
  gl_Position = projectionMatrix * viewMatrix * place;
}`;

// The checker of rendering/backdrop.py: box-filtered tiles of a third of the figure's
// height, fixed in the world (travel shows), fading into the sky around the look-at.
const FLOOR_FRAGMENT = `
uniform vec2 target;
uniform float tile;
uniform float radius;
uniform float viewHeight;
uniform float rowShift;
uniform vec3 skyTop;
uniform vec3 skyHorizon;
uniform vec3 floorLight;
uniform vec3 floorDark;
varying vec2 world;
float triangle(float t) { t = t / 2.0; return abs(t - floor(t) - 0.5); }
float squareMean(float x, float w) { return 2.0 * (triangle(x - w / 2.0) - triangle(x + w / 2.0)) / w; }
void main() {
  vec2 uv = world / tile;
  vec2 width = max(fwidth(uv), vec2(1e-4));
  float tiles = 0.5 - 0.5 * squareMean(uv.x, width.x) * squareMean(uv.y, width.y);
  vec2 near = (world - target) / tile;
  float fade = exp(-dot(near, near) / (radius * radius));
  fade *= clamp(1.5 - 2.5 * max(width.x, width.y), 0.0, 1.0);
  float row = clamp(1.0 - gl_FragCoord.y / viewHeight + rowShift, 0.0, 1.0);
  vec3 sky = mix(skyTop, skyHorizon, row);
  vec3 colour = mix(sky, floorLight, fade) + tiles * fade * (floorDark - floorLight);
  gl_FragColor = vec4(colour / 255.0, 1.0);
}`;

function floorMaterial(payload) {
  const vector = (c) => new THREE.Vector3(...c);
  const tile = payload.height / 3;
  return new THREE.ShaderMaterial({
    vertexShader: FLOOR_VERTEX,
    fragmentShader: FLOOR_FRAGMENT,
    // Drawn first and hiding nothing, as the rendered clips lay the figure over their
    // backdrop: a joint below the floor (a clip sinking, an anchor shaken apart) shows.
    depthWrite: false,
    uniforms: {
      target: { value: new THREE.Vector2() },
      tile: { value: tile },
      radius: { value: (1.6 * payload.distance * Math.tan((payload.fov * Math.PI) / 360)) / tile },
      viewHeight: { value: 1 },
      rowShift: { value: 0 },
      skyTop: { value: vector(PALETTE.skyTop) },
      skyHorizon: { value: vector(PALETTE.skyHorizon) },
      floorLight: { value: vector(PALETTE.floorLight) },
      floorDark: { value: vector(PALETTE.floorDark) },
    },
  });
}

function viewAxes(payload) {
  const az = (payload.azimuth * Math.PI) / 180;
  const el = (payload.elevation * Math.PI) / 180;
  const back = new THREE.Vector3(Math.cos(el) * Math.cos(az), Math.cos(el) * Math.sin(az), Math.sin(el));
  const forward = back.clone().negate();
  const right = new THREE.Vector3().crossVectors(forward, new THREE.Vector3(0, 0, 1)).normalize();
  return { back, forward, right };
}

// Where shadows fall per unit of height: rendering.framing.Framing.shadows.
function shadowFall(payload) {
  const { forward, right } = viewAxes(payload);
  const fall = new THREE.Vector2(0.8 * right.x - 0.6 * forward.x, 0.8 * right.y - 0.6 * forward.y);
  return fall.normalize().multiplyScalar(payload.shadowSlant);
}

// --- the figure ---------------------------------------------------------------------

const UP = new THREE.Vector3(0, 1, 0);

class Figure {
  constructor(payload, kind, scene) {
    this.payload = payload;
    const bones = payload.parents.map((p, j) => [p, j]).filter(([p]) => p >= 0);
    this.bones = bones;
    const body = kind === 'body';
    const sideColour = (side) => {
      const base = side > 0 ? PALETTE.left : side < 0 ? PALETTE.right : PALETTE.centre;
      return rgb(body ? mix(PALETTE.body, base, side === 0 ? 0 : BODY_TINT) : base);
    };
    // Sticks: a ball per joint over thinner tubes. Bodies: a capsule per bone (a tube
    // with a ball of its own radius at each end), so limbs join without seams.
    const balls = body
      ? bones.flatMap(([p, c]) => [[p, payload.bodyRadii[c], c], [c, payload.bodyRadii[c], c]])
      : payload.stickRadii.map((r, j) => [j, r, j]);
    this.ballJoints = balls.map(([j]) => j);
    this.ballRadii = balls.map(([, r]) => r);
    this.boneRadii = bones.map(([, c]) => (body ? payload.bodyRadii[c] : payload.stickBone));
    // Lambert shading for both: the cheapest lit shader to compile and run, which is what
    // software WebGL (no GPU) spends the first frame on.
    const material = new THREE.MeshLambertMaterial();
    const sphere = new THREE.SphereGeometry(1, 16, 10);
    const tube = new THREE.CylinderGeometry(1, 1, 1, 14, 1, true);
    this.balls = new THREE.InstancedMesh(sphere, material, balls.length);
    this.tubes = new THREE.InstancedMesh(tube, material, bones.length);
    balls.forEach(([, , owner], k) => this.balls.setColorAt(k, sideColour(payload.sides[owner])));
    bones.forEach(([, c], k) => this.tubes.setColorAt(k, sideColour(payload.sides[c])));
    // The shadow: the same shapes flattened onto the floor along the light, each pixel
    // darkened once (the stencil), as the rendered clips' soft shadow.
    const shade = new THREE.MeshBasicMaterial({
      color: rgb(PALETTE.shadow), transparent: true, opacity: SHADOW_OPACITY, depthWrite: false,
      stencilWrite: true, stencilRef: 1, stencilFunc: THREE.NotEqualStencilFunc,
      stencilZPass: THREE.ReplaceStencilOp,
    });
    this.shadowBalls = new THREE.InstancedMesh(sphere, shade, balls.length);
    this.shadowTubes = new THREE.InstancedMesh(tube, shade, bones.length);
    const fall = shadowFall(payload);
    const flatten = new THREE.Matrix4().set(
      1, 0, fall.x, 0,
      0, 1, fall.y, 0,
      0, 0, 0, 0.002 * payload.height,
      0, 0, 0, 1,
    );
    this.shadow = new THREE.Group();
    this.shadow.add(this.shadowBalls, this.shadowTubes);
    this.shadow.matrixAutoUpdate = false;
    this.shadow.matrix.copy(flatten);
    for (const mesh of [this.balls, this.tubes, this.shadowBalls, this.shadowTubes]) {
      mesh.frustumCulled = false;
      mesh.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    }
    this.shadow.visible = !payload.orthographic;
    scene.add(this.shadow, this.balls, this.tubes);
    this._a = new THREE.Vector3();
    this._b = new THREE.Vector3();
    this._m = new THREE.Matrix4();
    this._q = new THREE.Quaternion();
    this._s = new THREE.Vector3();
  }

  joint(frame, j, into) {
    const { positions, joints, step } = this.payload;
    const at = (frame * joints + j) * 3;
    return into.set(positions[at] * step, positions[at + 1] * step, positions[at + 2] * step);
  }

  pose(frame) {
    const { _a: a, _b: b, _m: m, _q: q, _s: s } = this;
    this.ballJoints.forEach((j, k) => {
      const r = this.ballRadii[k];
      m.compose(this.joint(frame, j, a), q.identity(), s.set(r, r, r));
      this.balls.setMatrixAt(k, m);
      this.shadowBalls.setMatrixAt(k, m);
    });
    this.bones.forEach(([p, c], k) => {
      this.joint(frame, p, a);
      this.joint(frame, c, b);
      const along = b.clone().sub(a);
      const length = Math.max(along.length(), 1e-6);
      q.setFromUnitVectors(UP, along.divideScalar(length));
      const r = this.boneRadii[k];
      m.compose(a.add(b).multiplyScalar(0.5), q, s.set(r, length, r));
      this.tubes.setMatrixAt(k, m);
      this.shadowTubes.setMatrixAt(k, m);
    });
    for (const mesh of [this.balls, this.tubes, this.shadowBalls, this.shadowTubes]) {
      mesh.instanceMatrix.needsUpdate = true;
    }
  }
}

// --- the element --------------------------------------------------------------------

export class MotionPlayer extends HTMLElement {
  static get observedAttributes() { return ['src', 'figure']; }

  constructor() {
    super();
    this.payload = null;
    this.frame = -1;
    this.plays = 0;
    this._loops = 0;
    this._size = [0, 0];
    this._drawnFirst = false;
  }

  connectedCallback() {
    if (!this.canvas) {
      this.canvas = document.createElement('canvas');
      this.canvas.style.cssText = 'display:block;width:100%;height:100%;touch-action:manipulation';
      this.appendChild(this.canvas);
      this.context = this.canvas.getContext('2d');
      this.tabIndex = this.tabIndex >= 0 ? this.tabIndex : 0;
      this.setAttribute('role', this.getAttribute('role') || 'img');
      // A tap or click toggles the page's playback; so does the space bar when focused.
      this.canvas.addEventListener('pointerup', (event) => {
        if (event.isPrimary) this._toggle('user');
      });
      this.addEventListener('keydown', (event) => {
        if (event.key === ' ') { event.preventDefault(); this._toggle('user'); }
      });
    }
    players.add(this);
    if (this.getAttribute('src') && !this.payload && !this._loading) this._load();
    wake();
  }

  disconnectedCallback() { players.delete(this); }

  attributeChangedCallback(name, before, after) {
    if (before === after || !this.isConnected) return;
    if (name === 'src') this._load();
    else if (this.payload) this._build();
  }

  /** Seconds of one loop. */
  get duration() { return this.payload ? this.payload.frames / this.payload.fps : NaN; }
  get paused() { return clock.paused; }
  get currentTime() { return this.payload ? now() % this.duration : 0; }
  set currentTime(seconds) { playback.seek(seconds); }
  play() { playback.play(); }
  pause() { playback.pause(); }
  replay() { playback.replay(); }

  _toggle(cause) {
    if (clock.paused) playback.play(cause); else playback.pause(cause);
  }

  async _load() {
    this._loading = true;
    this.payload = null;
    try {
      const response = await fetch(this.getAttribute('src'));
      if (!response.ok) throw new Error(`HTTP ${response.status}`);
      this.payload = parsePayload(await response.arrayBuffer());
      this._build();
      if (this.hasAttribute('autoplay')) playback.play('autoplay');
      wake();
    } catch (error) {
      this.dispatchEvent(new CustomEvent('error', { detail: { message: String(error) } }));
    } finally {
      this._loading = false;
    }
  }

  _build() {
    const payload = this.payload;
    this.scene = new THREE.Scene();
    this.scene.background = skyTexture();
    const { back, right } = viewAxes(payload);
    // Near and far planes and the view's size follow each frame's distance (_aim).
    if (payload.orthographic) {
      this.camera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0.01, 1);
    } else {
      this.camera = new THREE.PerspectiveCamera(payload.fov, 1, 0.01, 1);
    }
    this.camera.up.set(0, 0, 1);
    this._back = back;
    // Lights of the mesh style: a key from where shadows come, a fill from the upper
    // left of the camera, a rim from behind on the right.
    const fall = shadowFall(payload);
    this.scene.add(new THREE.AmbientLight(0xffffff, 1.5));
    const key = new THREE.DirectionalLight(0xffffff, 1.5);
    key.position.set(-fall.x, -fall.y, 1);
    const fill = new THREE.DirectionalLight(0xffffff, 0.8);
    fill.position.copy(back.clone().setZ(0).sub(right.clone().multiplyScalar(0.7)).setZ(0.6));
    const rim = new THREE.DirectionalLight(0xffffff, 0.35);
    rim.position.copy(back.clone().negate().setZ(0).add(right.clone().multiplyScalar(0.6)).setZ(0.4));
    for (const light of [key, fill, rim]) {
      this.scene.add(light, light.target);
    }
    if (!payload.orthographic) {
      this.floorMaterial = floorMaterial(payload);
      const floor = new THREE.Mesh(new THREE.PlaneGeometry(1, 1), this.floorMaterial);
      floor.scale.set(60 * payload.height, 60 * payload.height, 1);
      floor.frustumCulled = false;
      floor.renderOrder = -1;
      this.floor = floor;
      this.scene.add(floor);
    }
    this.figure = new Figure(payload, this.getAttribute('figure') === 'body' ? 'body' : 'stick', this.scene);
    this.frame = -1;
    this._loops = Math.floor((now() * payload.fps) / payload.frames);
  }

  _seeked() {
    if (this.payload) this._loops = Math.floor((now() * this.payload.fps) / this.payload.frames);
  }

  // Draw the clock's frame if it changed; return whether this player still needs frames.
  _draw(time) {
    const payload = this.payload;
    if (!payload || !this.isConnected) return Boolean(this._loading);
    const ratio = Math.min(window.devicePixelRatio || 1, 2);
    const width = Math.max(1, Math.round(this.canvas.clientWidth * ratio));
    const height = Math.max(1, Math.round(this.canvas.clientHeight * ratio));
    const step = Math.floor(time * payload.fps);
    const frame = step % payload.frames;
    const loops = Math.floor(step / payload.frames);
    const resized = width !== this._size[0] || height !== this._size[1];
    if (frame !== this.frame || resized) {
      if (resized) {
        this.canvas.width = width;
        this.canvas.height = height;
        this._size = [width, height];
      }
      this._render(frame, width, height);
      this.frame = frame;
      this.dataset.frame = String(frame);
      if (!this._drawnFirst) {
        this._drawnFirst = true;
        this.dispatchEvent(new CustomEvent('loadeddata', { detail: { time } }));
      }
    }
    while (loops > this._loops) {
      this._loops += 1;
      this.plays += 1;
      this.dispatchEvent(new CustomEvent('ended', { detail: { plays: this.plays, time } }));
    }
    return false;
  }

  // Point the camera as the clip's video films this frame (rendering.framing.Shot): the
  // look-at, the eye's distance, and the frame's window moved over the larger canvas (a
  // shift of the lens: the same scale). The window is in shares of the frame's height,
  // as the picture's scale is set by its height (the field of view is vertical).
  _aim(frame, width, height) {
    const payload = this.payload;
    const { step } = payload;
    const target = new THREE.Vector3(
      payload.targets[3 * frame] * step,
      payload.targets[3 * frame + 1] * step,
      payload.targets[3 * frame + 2] * step,
    );
    const distance = (payload.zooms[frame] / ZOOM_STEPS) * payload.distance;
    const aspect = width / height;
    const camera = this.camera;
    camera.near = 0.02 * distance;
    camera.far = 20 * distance + 20 * payload.height;
    if (payload.orthographic) {
      const half = distance * Math.tan((payload.fov * Math.PI) / 360);
      Object.assign(camera, { left: -half * aspect, right: half * aspect, top: half, bottom: -half });
    } else {
      camera.aspect = aspect;
    }
    const across = payload.windows[2 * frame] * payload.windowStep;
    const down = payload.windows[2 * frame + 1] * payload.windowStep;
    camera.setViewOffset(width, height, across * height, down * height, width, height);
    camera.position.copy(target).addScaledVector(this._back, distance);
    camera.lookAt(target);
    camera.updateMatrixWorld();
    return { target, distance, down };
  }

  /** Return where each joint of `frame` shows on the canvas, in its pixels ([x, y], y
   * down), as the frame is drawn (for checks against the rendered clip). */
  pixels(frame) {
    const [width, height] = this._size;
    if (!this.payload || !width) return null;
    this._aim(frame, width, height);
    const point = new THREE.Vector3();
    return Array.from({ length: this.payload.joints }, (_, j) => {
      this.figure.joint(frame, j, point).project(this.camera);
      return [((point.x + 1) / 2) * width, ((1 - point.y) / 2) * height];
    });
  }

  _render(frame, width, height) {
    const payload = this.payload;
    const gl = renderer();
    gl.setSize(width, height, false);
    const { target, distance, down } = this._aim(frame, width, height);
    // The sky's gradient runs over the frame's own rows where the window rests, as the
    // rendered backdrop's does (rendering/backdrop.py).
    this.scene.background.offset.set(0, -down);
    if (!payload.orthographic) {
      const uniforms = this.floorMaterial.uniforms;
      uniforms.target.value.set(target.x, target.y);
      uniforms.viewHeight.value = height;
      uniforms.rowShift.value = down;
      uniforms.radius.value = (1.6 * distance * Math.tan((payload.fov * Math.PI) / 360)) / uniforms.tile.value;
      this.floor.position.set(target.x, target.y, 0);
    }
    this.figure.pose(frame);
    gl.render(this.scene, this.camera);
    this.context.drawImage(gl.domElement, 0, 0, width, height, 0, 0, width, height);
  }
}

if (!customElements.get('motion-player')) customElements.define('motion-player', MotionPlayer);
