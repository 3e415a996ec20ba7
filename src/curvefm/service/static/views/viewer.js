// A viewport: one WebGL canvas showing one mesh (one draw call) with orbit/zoom/pan, clicks picked to the
// nearest vertex of the hit face, traced curves as tubes, and per-vertex uv / colours updated in place.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const CLICK_SLOP_PX = 5; // a press that moves further is an orbit/pan, not a click
// Which faces of the surface are drawn, by how they are wound seen from outside (mesh.js, outwardWinding): only
// those facing the viewer where that is known. The others are hidden behind them anyway, and a software renderer
// rasterises every face it is given: skipping them takes a fifth off each frame (SwiftShader, 28k vertices).
const SIDES = { 1: THREE.FrontSide, [-1]: THREE.BackSide, 0: THREE.DoubleSide };
const AXES = { x: new THREE.Vector3(1, 0, 0), y: new THREE.Vector3(0, 1, 0), z: new THREE.Vector3(0, 0, 1) };

// Software WebGL (SwiftShader, llvmpipe: headless browsers, machines without a GPU) draws on the CPU, where
// multisampling, high-DPI canvases and anisotropic filtering multiply the cost of every frame (measured with
// SwiftShader on a 30k-vertex mesh: 4x anisotropy alone doubles it); there the viewports do without.
const SOFTWARE_RENDERER = (() => {
  const gl = document.createElement("canvas").getContext("webgl2");
  const info = gl?.getExtension("WEBGL_debug_renderer_info");
  const name = info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : "";
  gl?.getExtension("WEBGL_lose_context")?.loseContext();
  return /swiftshader|llvmpipe|softpipe|software/i.test(name);
})();

export class Viewport {
  /** element: a figure with a .canvas-box child; frames: the FrameLoop that draws it (see frames.js). */
  constructor(element, frames) {
    this.frames = frames;
    this.box = element.querySelector(".canvas-box");
    this.renderer = new THREE.WebGLRenderer({ antialias: !SOFTWARE_RENDERER, alpha: true });
    this.renderer.setPixelRatio(SOFTWARE_RENDERER ? 1 : Math.min(window.devicePixelRatio, 2));
    this.box.append(this.renderer.domElement);

    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(30, 1, 0.05, 50);
    this.scene.add(this.camera);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x6e7380, 1.4));
    const headlight = new THREE.DirectionalLight(0xffffff, 2.0);
    headlight.position.set(0.6, 0.9, 0.4);
    headlight.target.position.set(0, 0, -1);
    this.camera.add(headlight, headlight.target);

    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener("change", () => this.frames.request(this));

    this.surface = new THREE.Group(); // the normalised frame: the mesh, its curves and markers
    this.scene.add(this.surface);
    this.mesh = null;
    this.curveTubes = new Map(); // key -> tube mesh
    // colour -> the material of every tube of that colour: three.js draws the objects of one material one after
    // another and sets its uniforms once for them (30 tubes: 2-3 ms less a frame in SwiftShader)
    this.tubeMaterials = new Map();
    this.curveGroup = new THREE.Group();
    this.surface.add(this.curveGroup);
    this.markers = new THREE.Group();
    this.surface.add(this.markers);
    this.commentGroup = new THREE.Group(); // review comments' markers (setCommentMarkers)
    this.surface.add(this.commentGroup);
    this.commentMarkers = [];
    this.suggested = new THREE.Group(); // the suggested curve: faint balls at its ends, a dashed line (setSuggestion)
    this.surface.add(this.suggested);
    this.suggestedRows = [];
    this.suggestedLine = null;
    // a translucent ball over a region of the surface (the weakest region of the maps), scaled in setMesh
    const ball = new THREE.MeshBasicMaterial({ color: 0x00e5ff, transparent: true, opacity: 0.45, depthWrite: false });
    this.highlight = new THREE.Mesh(new THREE.SphereGeometry(1, 24, 16), ball);
    this.highlight.visible = false;
    this.surface.add(this.highlight);
    this.raycaster = new THREE.Raycaster();

    new ResizeObserver(() => this.resize()).observe(this.box);
  }

  // -- the shape -------------------------------------------------------------------------------------------
  /** Show a decoded mesh (see mesh.js). Allocates the uv and colour attributes once; later updates only copy. */
  setMesh(mesh) {
    this.setCurves([]);
    this.setMarkers([]);
    this.setCommentMarkers([]);
    this.setSuggestion([]);
    if (this.mesh) {
      this.surface.remove(this.mesh);
      this.mesh.geometry.dispose();
      for (const material of this.materials) material.dispose();
    }
    const n = mesh.nVertices;
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(mesh.vertices, 3));
    geometry.setIndex(new THREE.BufferAttribute(mesh.faces, 1));
    geometry.computeVertexNormals();
    for (const [name, size] of [["uv", 2], ["color", 3]]) {
      const attribute = new THREE.BufferAttribute(new Float32Array(n * size), size);
      attribute.setUsage(THREE.DynamicDrawUsage);
      geometry.setAttribute(name, attribute);
    }
    geometry.computeBoundingSphere();
    // Lambert: matte shading shows the shape as well as a physically based material at two thirds of the cost
    // the surface is drawn a little deeper than it is, so curve tubes lying in it show whole
    const surface = { side: SIDES[mesh.winding], polygonOffset: true, polygonOffsetFactor: 2, polygonOffsetUnits: 2 };
    this.textured = new THREE.MeshLambertMaterial(surface);
    this.colored = new THREE.MeshLambertMaterial({ ...surface, vertexColors: true });
    this.tinted = new THREE.MeshLambertMaterial({ ...surface, vertexColors: true }); // texture x colours
    this.materials = [this.textured, this.colored, this.tinted];
    this.mesh = new THREE.Mesh(geometry, this.textured);
    this.surface.add(this.mesh);
    const { radius } = geometry.boundingSphere;
    this.tubeRadius = 0.011 * radius;
    this.markerGeometry?.dispose();
    this.markerGeometry = new THREE.SphereGeometry(3.5 * this.tubeRadius, 16, 12);
    this.highlight.scale.setScalar(0.09 * radius);
    this.setHighlight(-1);
    this.frames.request(this);
  }

  /** Turn the shape so its ``up`` axis points up and its ``towards`` axis (negated when ``flip``) at the viewer,
   * scaled into the unit sphere and centred (linked viewports share this frame). Returns the half extents of its
   * box. */
  orient({ up, towards, flip = false }) {
    const facing = AXES[towards].clone().multiplyScalar(flip ? -1 : 1);
    const side = new THREE.Vector3().crossVectors(AXES[up], facing);
    const rotation = new THREE.Matrix4().makeBasis(side, AXES[up], facing).transpose();
    this.surface.quaternion.setFromRotationMatrix(rotation);
    this.surface.scale.setScalar(1 / this.mesh.geometry.boundingSphere.radius);
    this.surface.position.set(0, 0, 0);
    this.surface.updateMatrixWorld(true);
    const box = new THREE.Box3().setFromObject(this.mesh);
    this.surface.position.sub(box.getCenter(new THREE.Vector3()));
    return box.getSize(new THREE.Vector3()).multiplyScalar(0.5);
  }

  /** Look along -z at the origin from where a box of these half extents fills the view with a margin. */
  resetCamera({ x, y, z }) {
    const tan = Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2));
    this.camera.position.set(0, 0, 1.15 * Math.max(y / tan, x / (tan * this.camera.aspect)) + z);
    this.controls.target.set(0, 0, 0);
    this.controls.update();
    this.frames.request(this);
  }

  /** Follow another viewport's camera (linked cameras: both shapes live in the same normalised frame). */
  copyCamera(other) {
    this.camera.position.copy(other.camera.position);
    this.camera.quaternion.copy(other.camera.quaternion);
    this.controls.target.copy(other.controls.target);
    this.camera.updateMatrixWorld();
    this.frames.request(this);
  }

  // -- what the surface shows ------------------------------------------------------------------------------
  /** Texture with per-vertex uv (Float32Array n x 2), copied into the existing attribute; ``tint(array)``, when
   * given, multiplies the white per-vertex colours it is handed (n x 3 linear RGB) and the texture by them. */
  showTexture(texture, uv, tint = null) {
    const attribute = this.mesh.geometry.attributes.uv;
    attribute.array.set(uv);
    attribute.needsUpdate = true;
    this.setTexture(texture);
    if (tint) this.showColors((out) => tint(out.fill(1)));
    this.mesh.material = tint ? this.tinted : this.textured;
    this.frames.request(this);
  }

  /** Per-vertex colours: fill(array) writes n x 3 linear RGB into the existing attribute's array. */
  showColors(fill) {
    const attribute = this.mesh.geometry.attributes.color;
    fill(attribute.array);
    attribute.needsUpdate = true;
    this.mesh.material = this.colored;
    this.frames.request(this);
  }

  setTexture(texture) {
    if (this.textured.map === texture) return;
    if (SOFTWARE_RENDERER) {
      texture.minFilter = THREE.LinearMipmapNearestFilter; // one mip level: trilinear costs a third more
    } else {
      texture.anisotropy = Math.min(8, this.renderer.capabilities.getMaxAnisotropy());
    }
    for (const material of [this.textured, this.tinted]) {
      material.map = texture;
      material.needsUpdate = true; // a map where there was none changes the shader
    }
  }

  // -- curves and clicked points (internal vertex ids) ----------------------------------------------------
  /** curves: [{ key, color, points: Float32Array n x 3 (the path's vertices), emphasis: bool }]. Tubes are rebuilt
   * only when they change. */
  setCurves(curves) {
    const wanted = new Map(curves.map((c) => [`${c.key}|${c.color}|${c.emphasis}`, c]));
    for (const [key, tube] of this.curveTubes) {
      if (!wanted.has(key)) {
        this.curveGroup.remove(tube);
        tube.geometry.dispose();
        this.curveTubes.delete(key);
      }
    }
    for (const [key, curve] of wanted) {
      if (!this.curveTubes.has(key)) {
        const tube = this.tube(curve.points, curve.color, curve.emphasis ? 1.8 : 1);
        this.curveTubes.set(key, tube);
        this.curveGroup.add(tube);
      }
    }
    this.frames.request(this);
  }

  showCurves(visible) {
    this.curveGroup.visible = visible;
    this.frames.request(this);
  }

  /** A tube along a path's vertices (packed xyz): one ring per vertex kept, and a vertex is kept once it is a
   * tube radius from the last one. A path runs along mesh edges, so finer rings add triangles, not shape: on a
   * scan of 110k vertices or more, whose edges are shorter than the radius, that halves a tube or better. */
  tube(path, color, widen) {
    const points = [];
    const last = new THREE.Vector3().fromArray(path, path.length - 3);
    for (let i = 0; i < path.length; i += 3) {
      const point = new THREE.Vector3().fromArray(path, i);
      const previous = points[points.length - 1];
      if (!previous || (point.distanceTo(previous) >= this.tubeRadius && point.distanceTo(last) >= this.tubeRadius)) {
        points.push(point);
      }
    }
    if (!last.equals(points[points.length - 1])) points.push(last);
    if (points.length === 1) points.push(points[0].clone().addScalar(1e-6 * this.tubeRadius));
    const curve = new THREE.CatmullRomCurve3(points, false, "centripetal");
    const geometry = new THREE.TubeGeometry(curve, points.length, widen * this.tubeRadius, 6, false);
    return new THREE.Mesh(geometry, this.tubeMaterial(color));
  }

  tubeMaterial(color) {
    if (!this.tubeMaterials.has(color)) {
      this.tubeMaterials.set(color, new THREE.MeshLambertMaterial({ color, emissive: color, emissiveIntensity: 0.25 }));
    }
    return this.tubeMaterials.get(color);
  }

  /** points: [{ vertex, color }] shown as small spheres (clicks of the curve being entered). */
  setMarkers(points) {
    for (const marker of [...this.markers.children]) {
      this.markers.remove(marker);
      marker.material.dispose();
    }
    const positions = this.mesh?.geometry.attributes.position;
    for (const { vertex, color } of points) {
      const marker = new THREE.Mesh(this.markerGeometry, new THREE.MeshLambertMaterial({ color }));
      marker.position.fromBufferAttribute(positions, vertex);
      this.markers.add(marker);
    }
    this.frames.request(this);
  }

  /** markers: [{ id, vertex (internal id), selected, resolved }]: review comments as pins (magenta, resolved grey,
   * the selected one yellow and larger). */
  setCommentMarkers(markers) {
    for (const pin of [...this.commentGroup.children]) {
      this.commentGroup.remove(pin);
      pin.material.dispose();
    }
    this.commentMarkers = markers.filter((marker) => marker.vertex >= 0);
    const positions = this.mesh?.geometry.attributes.position;
    for (const { vertex, selected, resolved } of this.commentMarkers) {
      const color = selected ? 0xffd400 : resolved ? 0x9aa0aa : 0xe6007e;
      const pin = new THREE.Mesh(this.markerGeometry, new THREE.MeshLambertMaterial({ color, emissive: color, emissiveIntensity: 0.3 }));
      pin.scale.setScalar(selected ? 1.8 : 1.2);
      pin.position.fromBufferAttribute(positions, vertex);
      this.commentGroup.add(pin);
    }
    this.frames.request(this);
  }

  /** The suggested curve: its ends (internal ids, -1: not placed yet) as faint grey balls, the one at ``moving``
   * (an index, or -1) yellow: the user's next click places it; and its ``path`` (packed xyz, or null while it is
   * traced) as a faint dashed line. The surface's polygon offset keeps the line, which runs along its edges, in
   * front of it. */
  setSuggestion(rows, moving = -1, path = null) {
    for (const object of [...this.suggested.children]) {
      this.suggested.remove(object);
      object.material.dispose();
      if (object === this.suggestedLine) object.geometry.dispose();
    }
    this.suggestedRows = [...rows];
    this.suggestedLine = path && path.length >= 6 ? this.dashedLine(path) : null;
    if (this.suggestedLine) this.suggested.add(this.suggestedLine);
    const positions = this.mesh?.geometry.attributes.position;
    rows.forEach((vertex, index) => {
      if (vertex < 0 || !positions) return;
      const color = index === moving ? 0xffb000 : 0x5a6070;
      const material = new THREE.MeshBasicMaterial({ color, transparent: true, opacity: 0.5, depthWrite: false });
      const ball = new THREE.Mesh(this.markerGeometry, material);
      ball.scale.setScalar(1.6);
      ball.position.fromBufferAttribute(positions, vertex);
      this.suggested.add(ball);
    });
    this.frames.request(this);
  }

  dashedLine(path) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(path, 3));
    const dash = 2 * this.tubeRadius;
    const material = new THREE.LineDashedMaterial({ color: 0x3a4050, dashSize: dash, gapSize: dash, transparent: true, opacity: 0.7 });
    const line = new THREE.Line(geometry, material);
    line.computeLineDistances();
    return line;
  }

  /** Ring a region: a translucent ball around ``vertex`` (internal id), or none (-1). */
  setHighlight(vertex) {
    this.highlightedVertex = vertex;
    this.highlight.visible = vertex >= 0;
    if (vertex >= 0) this.highlight.position.fromBufferAttribute(this.mesh.geometry.attributes.position, vertex);
    this.frames.request(this);
  }

  // -- picking ---------------------------------------------------------------------------------------------
  /** The internal id of the vertex nearest to where the ray through (clientX, clientY) first hits the
   * mesh (the nearest corner of the hit face), or -1 when it misses. */
  pick(clientX, clientY) {
    if (!this.mesh) return -1;
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(
      ((clientX - rect.left) / rect.width) * 2 - 1,
      1 - ((clientY - rect.top) / rect.height) * 2,
    );
    this.raycaster.setFromCamera(ndc, this.camera);
    const [hit] = this.raycaster.intersectObject(this.mesh, false);
    if (!hit) return -1;
    const local = this.mesh.worldToLocal(hit.point.clone());
    const positions = this.mesh.geometry.attributes.position;
    const corner = new THREE.Vector3();
    let best = -1;
    let bestDistance = Infinity;
    for (const vertex of [hit.face.a, hit.face.b, hit.face.c]) {
      const distance = corner.fromBufferAttribute(positions, vertex).distanceToSquared(local);
      if (distance < bestDistance) [best, bestDistance] = [vertex, distance];
    }
    return best;
  }

  /** Where vertex (internal id) is drawn, in client pixels, and whether a click there picks it. */
  vertexToScreen(vertex) {
    const point = new THREE.Vector3().fromBufferAttribute(this.mesh.geometry.attributes.position, vertex);
    const ndc = this.mesh.localToWorld(point).project(this.camera);
    const rect = this.renderer.domElement.getBoundingClientRect();
    const x = rect.left + ((ndc.x + 1) / 2) * rect.width;
    const y = rect.top + ((1 - ndc.y) / 2) * rect.height;
    const inside = Math.abs(ndc.x) < 1 && Math.abs(ndc.y) < 1 && Math.abs(ndc.z) < 1;
    return { x, y, visible: inside && this.pick(x, y) === vertex };
  }

  /** handler(internalVertex, pointerEvent) runs on a click on the mesh (a press that did not move). */
  onPick(handler) {
    const canvas = this.renderer.domElement;
    let down = null;
    canvas.addEventListener("pointerdown", (event) => {
      down = event.button === 0 ? { x: event.clientX, y: event.clientY, id: event.pointerId } : null;
    });
    canvas.addEventListener("pointerup", (event) => {
      const press = down;
      down = null;
      if (!press || press.id !== event.pointerId) return;
      if (Math.hypot(event.clientX - press.x, event.clientY - press.y) > CLICK_SLOP_PX) return;
      const vertex = this.pick(event.clientX, event.clientY);
      if (vertex >= 0) handler(vertex, event);
    });
  }

  // -- drawing ---------------------------------------------------------------------------------------------
  resize() {
    const { clientWidth: width, clientHeight: height } = this.box;
    if (!width || !height) return;
    this.renderer.setSize(width, height);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this.frames.request(this);
  }

  draw() {
    this.renderer.render(this.scene, this.camera);
  }

  /** Draw now; resolves with performance.now() once the pixels exist (FrameLoop.drawn). */
  drawn() {
    return this.frames.drawn(this);
  }

  /** Resolves with performance.now() when the commands issued so far have completed: a fence, polled
   * without blocking the page (WebGL updates its status between tasks). */
  pixelsDone() {
    const gl = this.renderer.getContext();
    const fence = gl.fenceSync(gl.SYNC_GPU_COMMANDS_COMPLETE, 0);
    gl.flush();
    return new Promise((resolve) => {
      const poll = () => {
        if (gl.clientWaitSync(fence, 0, 0) === gl.TIMEOUT_EXPIRED) {
          setTimeout(poll, 1);
          return;
        }
        gl.deleteSync(fence);
        resolve(performance.now());
      };
      poll();
    });
  }

  /** Draw, once and into one pixel, every material the viewport will use (the surface textured and
   * coloured, tubes and markers): shaders are compiled on first use, which would otherwise fall on a click. */
  warmUp() {
    const plain = new THREE.MeshLambertMaterial();
    const samples = [...this.materials, plain].map((m) => new THREE.Mesh(this.mesh.geometry, m));
    this.surface.add(...samples);
    const highlighted = this.highlight.visible;
    this.highlight.visible = true;
    const viewport = this.renderer.getViewport(new THREE.Vector4());
    this.renderer.setViewport(0, 0, 1, 1);
    this.renderer.render(this.scene, this.camera);
    this.renderer.setViewport(viewport);
    this.highlight.visible = highlighted;
    this.surface.remove(...samples);
    plain.dispose();
    this.frames.request(this);
  }
}
