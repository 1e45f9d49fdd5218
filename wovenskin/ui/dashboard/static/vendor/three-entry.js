export {
  AmbientLight, ArrowHelper, BufferGeometry, Float32BufferAttribute, AxesHelper, BoxGeometry, CanvasTexture, CapsuleGeometry, Color,
  CylinderGeometry, DirectionalLight, GridHelper, Group, HemisphereLight, Matrix4, Mesh,
  MeshBasicMaterial, MeshStandardMaterial, NearestFilter, PerspectiveCamera, PlaneGeometry,
  Quaternion, Scene, SphereGeometry, SRGBColorSpace, Vector3, WebGLRenderer, DoubleSide,
} from 'three';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
