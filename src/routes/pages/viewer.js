// citymesh's three.js viewer: streams the XYZ tiles around a place, each placed from the origin
// its GLB records (scenes[0].extras.origin), with orbit controls and sun-like light.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';

const state = window.citymeshViewer = { tilesLoaded: 0, tilesFailed: 0, tilesWanted: 0, ready: false, errors: [] };
const d = window.CITYMESH_DEFAULTS;
const q = new URLSearchParams(location.search);
const lon0 = parseFloat(q.get('lon') ?? d.lon);
const lat0 = parseFloat(q.get('lat') ?? d.lat);
const zoom = parseInt(q.get('zoom') ?? d.zoom, 10);
const radius = parseInt(q.get('radius') ?? '1', 10);
const empty = q.has('empty');
// `?roofs=classified`: roofs from the roof classifier's predictions where OSM has no roof:shape;
// `?roofs=inferred`: from the roof prior learned from the area's tagged buildings.
const roofs = ['classified', 'inferred'].includes(q.get('roofs')) ? q.get('roofs') : 'osm';
// `?encoding=plain|quantized|meshopt`: how the tiles store vertices (meshopt, the smallest, by
// default; three.js decodes it with its MeshoptDecoder).
const encoding = ['plain', 'quantized', 'meshopt'].includes(q.get('encoding')) ? q.get('encoding') : 'meshopt';
const tileQuery = '?' + new URLSearchParams(roofs !== 'osm' ? { roofs, encoding } : { encoding });
state.roofs = roofs;
state.encoding = encoding;
document.getElementById('where').textContent = `${lon0.toFixed(5)} E, ${lat0.toFixed(5)} N, tiles of zoom ${zoom}`;

// Metres per degree at the view's latitude (WGS84), as citymesh's local frames use.
const a = 6378137, e2 = 6.69437999014e-3, phi = lat0 * Math.PI / 180;
const w = Math.sqrt(1 - e2 * Math.sin(phi) ** 2);
const mLon = a / w * Math.cos(phi) * Math.PI / 180, mLat = a * (1 - e2) / (w * w * w) * Math.PI / 180;

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(innerWidth, innerHeight);
document.body.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xbcd4e6);
const camera = new THREE.PerspectiveCamera(50, innerWidth / innerHeight, 1, 20000);
// `?camera=x,y,z`: where the camera stands, metres east, up and south of the place shown.
const at = (q.get('camera') ?? '').split(',').map(Number);
if (at.length === 3 && at.every(Number.isFinite)) camera.position.set(at[0], at[1], at[2]);
else camera.position.set(-350, 450, 550);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0, 0);
controls.maxPolarAngle = Math.PI * 0.49;
scene.add(new THREE.HemisphereLight(0xdde8ff, 0x6b5a40, 1.1));
const sun = new THREE.DirectionalLight(0xfff4e0, 2.2);
sun.position.set(-400, 700, 300);
scene.add(sun);

// The tiles around the place.
const n = 2 ** zoom;
const tx = Math.floor((lon0 + 180) / 360 * n);
const latR = lat0 * Math.PI / 180;
const ty = Math.floor((1 - Math.log(Math.tan(latR) + 1 / Math.cos(latR)) / Math.PI) / 2 * n);
const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
let baseHeight = null;
const group = new THREE.Group();
scene.add(group);
function done() {
  if (state.tilesLoaded + state.tilesFailed === state.tilesWanted) state.ready = true;
}
if (!empty) {
  for (let dx = -radius; dx <= radius; dx++) {
    for (let dy = -radius; dy <= radius; dy++) {
      state.tilesWanted++;
      loader.load(`/tiles/${zoom}/${tx + dx}/${ty + dy}.glb${tileQuery}`, (gltf) => {
        const o = gltf.scene.userData.origin;
        gltf.scene.position.set((o.lon - lon0) * mLon, o.height, -(o.lat - lat0) * mLat);
        group.add(gltf.scene);
        // Sit the view on the ground of the first tile.
        if (baseHeight === null) {
          const box = new THREE.Box3().setFromObject(gltf.scene);
          baseHeight = box.min.y;
          group.position.y = -baseHeight;
        }
        state.tilesLoaded++;
        done();
      }, undefined, (err) => { state.tilesFailed++; state.errors.push(String(err)); done(); });
    }
  }
} else {
  state.ready = true;
}

// The figures of the area shown.
const span = (radius + 0.5) * 360 / n;
fetch(`/scene/stats?bbox=${lon0 - span},${lat0 - span * 0.6},${lon0 + span},${lat0 + span * 0.6}&roofs=${roofs}`)
  .then((r) => r.ok ? r.json() : null)
  .then((s) => {
    if (!s) return;
    state.stats = s;
    const rows = [['buildings', s.buildings.generated], ['triangles', s.triangles],
      ['flat roofs', s.flat_roof_percent.toFixed(1) + ' %'], ['roof shapes from tags', s.roof_shape_from_tag_percent.toFixed(1) + ' %'],
      ['generated in', s.generation_ms.toFixed(1) + ' ms']];
    if (s.classified_roofs) {
      rows.splice(4, 0, ['roof shapes from the classifier', s.roof_shape_from_classifier_percent.toFixed(1) + ' %'],
        ['roofs still pending', s.classified_roofs.pending]);
    }
    if (s.inferred_roofs) {
      const p = s.inferred_roofs.priors;
      const acc = p.length === 1 && p[0].cross_validated_accuracy !== null
        ? ` (cross-validated ${(100 * p[0].cross_validated_accuracy).toFixed(1)} %)` : '';
      rows.splice(4, 0, ['roof shapes inferred from tags nearby', s.roof_shape_inferred_percent.toFixed(1) + ' %' + acc]);
    }
    if (s.imagery_attribution) rows.push(['roofs classified from', s.imagery_attribution]);
    document.getElementById('stats').innerHTML = rows.map(([k, v]) => `<tr><td>${k}</td><td>${v}</td></tr>`).join('');
  }).catch(() => {});

addEventListener('resize', () => {
  camera.aspect = innerWidth / innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(innerWidth, innerHeight);
});
renderer.setAnimationLoop(() => { controls.update(); renderer.render(scene, camera); });
