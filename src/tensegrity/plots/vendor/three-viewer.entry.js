export {
  WebGLRenderer, Scene, PerspectiveCamera, OrthographicCamera, Color, BufferGeometry, BufferAttribute,
  Float32BufferAttribute, LineSegments, LineBasicMaterial, LineDashedMaterial, InstancedMesh,
  CylinderGeometry, SphereGeometry, ConeGeometry, MeshLambertMaterial, MeshBasicMaterial,
  AmbientLight, DirectionalLight, Matrix4, Vector3, Vector2, Quaternion, Raycaster, Object3D,
  DynamicDrawUsage, Box3, Sphere, GridHelper, AxesHelper, REVISION
} from 'three';
export { OrbitControls } from 'three/addons/controls/OrbitControls.js';
