// The interactive viewer of a tensegrity run (tensegrity.plots.viewer), inlined into its HTML
// page after three.js (window.THREE, the vendored build in vendor/).  It reads the run from the
// JSON in <script id="tensegrity-data">: node positions and tensions as base64 little-endian
// Float32 (frame after frame), members as base64 Int32 pairs, and, when the members have a
// design, their utilisation (base64 Float32, rods and tendons frame after frame) with a colour
// mode switch "tension" / "utilisation"; a run with planes adds data.contacts: each plane's patch
// (four corners) and grid cell, and each contact pair's node (base64 Int32) and mode at each frame
// (base64 Int8, frame after frame: 0 free, 1 slip, 2 stick).  SI units: m, s, N, J.
// Colours: the colour map, the legend and data.colors are sRGB, as CSS and matplotlib's; three.js
// keeps colours in its linear working space and encodes them to sRGB when it draws.  A material's
// colour, and a colour set with setRGB(..., "srgb"), is converted on the way in; a vertex colour
// attribute is not: it must hold linear values (drawnRGB), or it is encoded to sRGB twice.
// window.tensegrityViewer is its interface for scripts and tests.
(function () {
  "use strict";
  const T = window.THREE;
  const data = JSON.parse(document.getElementById("tensegrity-data").textContent);

  function bytes(b64) {
    const text = atob(b64);
    const out = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
    return out.buffer;
  }
  const F = data.n_frames, N = data.n_nodes, R = data.n_rods, S = data.n_tendons;
  const positions = new Float32Array(bytes(data.node_position)); // F * N * 3
  const tensions = new Float32Array(bytes(data.tendon_tension)); // F * S
  const rods = new Int32Array(bytes(data.rod_nodes)); // R * 2
  const tendons = new Int32Array(bytes(data.tendon_nodes)); // S * 2
  const times = data.t;
  const [lowT, highT] = data.tension_range;
  const lut = data.colormap; // 256 [r, g, b] in 0..1
  const usage = data.utilisation ? { // the members' utilisation, or null without a design
    rods: new Float32Array(bytes(data.utilisation.rods)), // F * R
    tendons: new Float32Array(bytes(data.utilisation.tendons)), // F * S
    high: data.utilisation.high, // top of the colour scale, >= 1
    failure: [1, 3, 5].map((i) => parseInt(data.colors.failure.slice(i, i + 2), 16) / 255),
  } : null;
  let mode = "tension"; // or "utilisation" (with a design)

  // ---------------------------------------------------------------- scene and camera
  const view = document.getElementById("view");
  const renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setClearColor(0xffffff, 1);
  view.appendChild(renderer.domElement);
  const scene = new T.Scene();
  const low = new T.Vector3(...data.bounds[0]), high = new T.Vector3(...data.bounds[1]);
  const centre = low.clone().add(high).multiplyScalar(0.5);
  const size = Math.max(high.clone().sub(low).length(), 1e-6);
  const camera = new T.PerspectiveCamera(40, 1, size * 1e-3, size * 100);
  if (data.dim === 2) camera.position.set(centre.x, centre.y, centre.z + 1.6 * size);
  else {
    camera.up.set(0, 0, 1);
    camera.position.set(centre.x + 1.1 * size, centre.y - 0.9 * size, centre.z + 0.7 * size);
  }
  const controls = new T.OrbitControls(camera, renderer.domElement);
  controls.target.copy(centre);
  controls.update();
  scene.add(new T.AmbientLight(0xffffff, 1.6));
  const sun = new T.DirectionalLight(0xffffff, 1.8);
  sun.position.set(1, -1, 2);
  scene.add(sun);
  const everywhere = new T.Sphere(centre, 0.5 * size + 1e-6); // every node of every frame

  // ---------------------------------------------------------------- members
  const rodRadius = data.rod_radius;
  const rodMesh = new T.InstancedMesh(
    new T.CylinderGeometry(1, 1, 1, 8, 1, false),
    new T.MeshLambertMaterial({ color: usage ? 0xffffff : data.colors.rod }), // (per rod)
    Math.max(R, 1)
  );
  const rodColor = new T.Color(data.colors.rod), drawnColor = new T.Color(), rgb = [0, 0, 0];
  rodMesh.count = R;
  rodMesh.instanceMatrix.setUsage(T.DynamicDrawUsage);
  rodMesh.frustumCulled = false;
  rodMesh.boundingSphere = everywhere;
  scene.add(rodMesh);

  function lines(material, attributes) {
    const geometry = new T.BufferGeometry();
    for (const [name, width] of attributes) {
      const attribute = new T.BufferAttribute(new Float32Array(Math.max(2 * S, 2) * width), width);
      attribute.setUsage(T.DynamicDrawUsage);
      geometry.setAttribute(name, attribute);
    }
    geometry.boundingSphere = everywhere;
    const object = new T.LineSegments(geometry, material);
    object.frustumCulled = false;
    scene.add(object);
    return object;
  }
  const taut = lines(new T.LineBasicMaterial({ vertexColors: true }), [["position", 3], ["color", 3]]);
  const slack = lines(
    new T.LineDashedMaterial({ color: data.colors.slack, dashSize: 0.02 * size, gapSize: 0.015 * size }),
    [["position", 3], ["lineDistance", 1]]
  );
  const tautIds = new Int32Array(Math.max(S, 1)), slackIds = new Int32Array(Math.max(S, 1));

  function markers(nodes, geometry, color) {
    const mesh = new T.InstancedMesh(geometry, new T.MeshLambertMaterial({ color }), Math.max(nodes.length, 1));
    mesh.count = nodes.length;
    mesh.frustumCulled = false;
    mesh.boundingSphere = everywhere;
    scene.add(mesh);
    return { mesh, nodes };
  }
  const r = rodRadius;
  const nodeMarkers = [
    markers(data.point_masses, new T.SphereGeometry(2.6 * r, 16, 12), data.colors.rod),
    markers(data.joints, new T.SphereGeometry(2.0 * r, 16, 12), data.colors.joint),
    markers(data.fixed, new T.ConeGeometry(3.0 * r, 6.0 * r, 12).rotateX(Math.PI / 2), data.colors.fixed),
  ];

  // ---------------------------------------------------------------- planes and contacts
  const SLIP = 1, STICK = 2;
  const contacts = data.contacts ? { // the planes and contact modes, or null without planes
    n: data.contacts.n_pairs,
    node: new Int32Array(bytes(data.contacts.node)), // CP
    mode: new Int8Array(bytes(data.contacts.mode)), // F * CP
  } : null;
  let contactMesh = null, contactNode = null, contactMode = null; // (the marked ends, this frame)
  if (contacts) {
    const c = data.colors;
    const patchMaterial = new T.MeshBasicMaterial({ color: c.plane, transparent: true,
      opacity: c.plane_alpha, side: 2, depthWrite: false }); // (2: THREE.DoubleSide)
    const gridMaterial = new T.LineBasicMaterial({ color: c.plane_grid });
    for (const corners of data.contacts.patch) { // a quad, and its grid: lines every cell
      const [c0, c1, c2, c3] = corners.map((x) => new T.Vector3(...x));
      // (one instance of an InstancedMesh: the vendored build has no Mesh)
      const quad = new T.InstancedMesh(
        new T.BufferGeometry().setFromPoints([c0, c1, c2, c0, c2, c3]), patchMaterial, 1);
      quad.setMatrixAt(0, new T.Matrix4());
      scene.add(quad);
      const du = c1.clone().sub(c0), dv = c3.clone().sub(c0), points = [];
      const nu = Math.max(1, Math.round(du.length() / data.contacts.cell));
      const nv = Math.max(1, Math.round(dv.length() / data.contacts.cell));
      for (let i = 0; i <= nu; i++) {
        const o = c0.clone().addScaledVector(du, i / nu);
        points.push(o, o.clone().add(dv));
      }
      for (let j = 0; j <= nv; j++) {
        const o = c0.clone().addScaledVector(dv, j / nv);
        points.push(o, o.clone().add(du));
      }
      scene.add(new T.LineSegments(new T.BufferGeometry().setFromPoints(points), gridMaterial));
    }
    contactMesh = new T.InstancedMesh(new T.SphereGeometry(2.2 * rodRadius, 16, 12),
      new T.MeshLambertMaterial({ color: 0xffffff }), Math.max(contacts.n, 1)); // (colour per end)
    contactMesh.count = 0;
    contactMesh.frustumCulled = false;
    contactMesh.boundingSphere = everywhere;
    contactMesh.setColorAt(0, new T.Color(c.stick)); // (makes instanceColor)
    scene.add(contactMesh);
    contactNode = new Int32Array(Math.max(contacts.n, 1));
    contactMode = new Int8Array(Math.max(contacts.n, 1));
  }
  const stickColor = new T.Color(data.colors.stick || 0), slipColor = new T.Color(data.colors.slip || 0);
  // the ends in contact in frame k (a node's mode: stick if any of its pairs sticks), into
  // contactNode and contactMode; their number
  function contactsAt(k) {
    const mode = contacts.mode.subarray(k * contacts.n, (k + 1) * contacts.n), at = new Map();
    for (let i = 0; i < contacts.n; i++) {
      if (mode[i] === SLIP || mode[i] === STICK) at.set(contacts.node[i], Math.max(at.get(contacts.node[i]) || 0, mode[i]));
    }
    let m = 0;
    for (const [n, which] of [...at].sort((x, y) => x[0] - y[0])) { contactNode[m] = n; contactMode[m++] = which; }
    return m;
  }

  // ---------------------------------------------------------------- one frame
  let current = 0;
  const a = new T.Vector3(), b = new T.Vector3(), up = new T.Vector3(0, 1, 0);
  const quaternion = new T.Quaternion(), scale = new T.Vector3(), matrix = new T.Matrix4();

  // the colour of a value on the colour map over low..high (clipped), into out[at..at+2]
  function colorOf(value, low, high, out, at) {
    let x = (value - low) / (high - low);
    x = Math.min(Math.max(x, 0), 1);
    const c = lut[Math.round(x * (lut.length - 1))];
    out[at] = c[0]; out[at + 1] = c[1]; out[at + 2] = c[2];
  }
  // a utilisation's colour: the map over 0..high, the failure colour above 1 (figures.py's rule)
  function utilisationColor(u, out, at) {
    if (u > 1) { out[at] = usage.failure[0]; out[at + 1] = usage.failure[1]; out[at + 2] = usage.failure[2]; }
    else colorOf(u, 0, usage.high, out, at);
  }
  // tendon j's colour in frame k by the colour mode (sRGB, the legend's), in rgb
  function tendonRGB(k, j) {
    if (mode === "utilisation") utilisationColor(usage.tendons[k * S + j], rgb, 0);
    else colorOf(tensions[k * S + j], lowT, highT, rgb, 0);
    return rgb;
  }
  // srgb ([r, g, b], 0..1) as three.js draws it (in its linear working space), in drawnColor
  function drawnRGB(srgb) {
    return drawnColor.setRGB(srgb[0], srgb[1], srgb[2], "srgb");
  }

  function setFrame(k) {
    k = Math.min(Math.max(Math.round(k), 0), F - 1);
    current = k;
    const p = positions.subarray(k * N * 3, (k + 1) * N * 3);
    const t = tensions.subarray(k * S, (k + 1) * S);
    for (let i = 0; i < R; i++) {
      const u = 3 * rods[2 * i], v = 3 * rods[2 * i + 1];
      a.set(p[u], p[u + 1], p[u + 2]);
      b.set(p[v], p[v + 1], p[v + 2]);
      const length = a.distanceTo(b);
      b.sub(a);
      if (length > 0) quaternion.setFromUnitVectors(up, b.multiplyScalar(1 / length));
      a.add(b.multiplyScalar(0.5 * length));
      scale.set(r, length, r);
      matrix.compose(a, quaternion, scale);
      rodMesh.setMatrixAt(i, matrix);
      if (usage && mode === "utilisation") {
        utilisationColor(usage.rods[k * R + i], rgb, 0);
        rodMesh.setColorAt(i, drawnRGB(rgb));
      } else if (usage) rodMesh.setColorAt(i, rodColor);
    }
    rodMesh.instanceMatrix.needsUpdate = true;
    if (rodMesh.instanceColor) rodMesh.instanceColor.needsUpdate = true;
    const tp = taut.geometry.attributes.position.array, tc = taut.geometry.attributes.color.array;
    const sp = slack.geometry.attributes.position.array, sd = slack.geometry.attributes.lineDistance.array;
    let nt = 0, ns = 0;
    for (let j = 0; j < S; j++) {
      const u = 3 * tendons[2 * j], v = 3 * tendons[2 * j + 1];
      if (t[j] > 0) {
        const o = 6 * nt;
        for (let c = 0; c < 3; c++) { tp[o + c] = p[u + c]; tp[o + 3 + c] = p[v + c]; }
        drawnRGB(tendonRGB(k, j)).toArray(tc, o);
        drawnColor.toArray(tc, o + 3);
        tautIds[nt++] = j;
      } else {
        const o = 6 * ns;
        for (let c = 0; c < 3; c++) { sp[o + c] = p[u + c]; sp[o + 3 + c] = p[v + c]; }
        sd[2 * ns] = 0;
        sd[2 * ns + 1] = Math.hypot(p[v] - p[u], p[v + 1] - p[u + 1], p[v + 2] - p[u + 2]);
        slackIds[ns++] = j;
      }
    }
    taut.geometry.setDrawRange(0, 2 * nt);
    slack.geometry.setDrawRange(0, 2 * ns);
    for (const name of ["position", "color"]) taut.geometry.attributes[name].needsUpdate = true;
    for (const name of ["position", "lineDistance"]) slack.geometry.attributes[name].needsUpdate = true;
    for (const { mesh, nodes } of nodeMarkers) {
      nodes.forEach((n, i) => {
        a.set(p[3 * n], p[3 * n + 1], p[3 * n + 2]);
        matrix.makeTranslation(a.x, a.y, a.z);
        mesh.setMatrixAt(i, matrix);
      });
      mesh.instanceMatrix.needsUpdate = true;
    }
    let marked = "";
    if (contacts) {
      const m = contactsAt(k);
      let sticking = 0;
      for (let i = 0; i < m; i++) {
        const n = contactNode[i];
        matrix.makeTranslation(p[3 * n], p[3 * n + 1], p[3 * n + 2]);
        contactMesh.setMatrixAt(i, matrix);
        contactMesh.setColorAt(i, contactMode[i] === STICK ? stickColor : slipColor);
        if (contactMode[i] === STICK) sticking++;
      }
      contactMesh.count = m;
      contactMesh.instanceMatrix.needsUpdate = true;
      contactMesh.instanceColor.needsUpdate = true;
      marked = `, ${sticking} ends sticking, ${m - sticking} slipping`;
    }
    slider.value = String(k);
    const e = data.energy;
    clock.textContent = `t = ${times[k].toFixed(3)} s` +
      (e.total ? `   E = ${e.total[k].toPrecision(6)} J   E_kin = ${e.kinetic[k].toPrecision(4)} J` : "");
    counts.textContent = `${R} rods, ${S} tendons, ${ns} slack (dashed)${marked}`;
    if (pinned) showInfo(pinned);
    renderer.render(scene, camera);
  }

  // ---------------------------------------------------------------- what a member is
  function member(kind, id) {
    const k = current, p = positions.subarray(k * N * 3, (k + 1) * N * 3);
    const pair = kind === "rod" ? rods : tendons;
    const u = 3 * pair[2 * id], v = 3 * pair[2 * id + 1];
    const length = Math.hypot(p[v] - p[u], p[v + 1] - p[u + 1], p[v + 2] - p[u + 2]);
    const info = { kind, id, name: kind === "rod" ? `rod ${id}` : data.tendon_name[id],
      nodes: [pair[2 * id], pair[2 * id + 1]], length };
    if (kind === "tendon") info.tension = tensions[k * S + id];
    if (usage) info.utilisation = kind === "rod" ? usage.rods[k * R + id] : usage.tendons[k * S + id];
    return info;
  }
  const raycaster = new T.Raycaster();
  raycaster.params.Line.threshold = 0.01 * size;
  function pickAt(x, y) {
    const box = renderer.domElement.getBoundingClientRect();
    const pointer = new T.Vector2(((x - box.left) / box.width) * 2 - 1, -((y - box.top) / box.height) * 2 + 1);
    raycaster.setFromCamera(pointer, camera);
    const hit = raycaster.intersectObjects([rodMesh, taut, slack], false)[0];
    if (!hit) return null;
    if (hit.object === rodMesh) return { kind: "rod", id: hit.instanceId };
    const ids = hit.object === taut ? tautIds : slackIds;
    return { kind: "tendon", id: ids[Math.floor(hit.index / 2)] };
  }
  function describe(info) {
    let text = `${info.name} (nodes ${info.nodes[0]}-${info.nodes[1]})\nlength ${info.length.toPrecision(5)} m`;
    if (info.kind === "tendon") text += info.tension > 0 ? `\ntension ${info.tension.toPrecision(5)} N` : "\nslack (tension 0 N)";
    if (info.utilisation !== undefined) text += `\nutilisation ${info.utilisation.toPrecision(4)}${info.utilisation > 1 ? " (fails)" : ""}`;
    return text;
  }
  let pinned = null;
  function showInfo(which) { infoBox.textContent = which ? describe(member(which.kind, which.id)) : ""; }
  let hoverQueued = false;
  renderer.domElement.addEventListener("pointermove", (event) => {
    if (hoverQueued) return;
    hoverQueued = true;
    requestAnimationFrame(() => {
      hoverQueued = false;
      const which = pickAt(event.clientX, event.clientY);
      tip.style.display = which ? "block" : "none";
      if (which) {
        tip.textContent = describe(member(which.kind, which.id));
        tip.style.left = `${event.clientX + 14}px`;
        tip.style.top = `${event.clientY + 14}px`;
      }
    });
  });
  renderer.domElement.addEventListener("click", (event) => {
    pinned = pickAt(event.clientX, event.clientY);
    showInfo(pinned);
  });

  // ---------------------------------------------------------------- controls and legend
  const slider = document.getElementById("time");
  const clock = document.getElementById("clock");
  const counts = document.getElementById("counts");
  const infoBox = document.getElementById("info");
  const tip = document.getElementById("tip");
  const playButton = document.getElementById("play");
  const speedBox = document.getElementById("speed");
  slider.max = String(F - 1);
  slider.addEventListener("input", () => { playing = false; playButton.textContent = "play"; setFrame(+slider.value); });
  const span = times[F - 1] - times[0];
  const baseRate = span > 0 ? span / Math.min(span, data.max_real_time) : 1; // run seconds per second
  let playing = false, clockTime = times[0], last = null;
  function tick(now) {
    if (playing) {
      if (last !== null) clockTime += ((now - last) / 1000) * baseRate * +speedBox.value;
      last = now;
      if (clockTime > times[F - 1]) clockTime = times[0];
      let k = current;
      while (k + 1 < F && times[k + 1] <= clockTime) k++;
      if (times[k] > clockTime) k = 0;
      if (k !== current) setFrame(k);
    } else last = null;
    requestAnimationFrame(tick);
  }
  playButton.addEventListener("click", () => {
    playing = !playing && F > 1;
    playButton.textContent = playing ? "pause" : "play";
    clockTime = times[current];
  });
  document.getElementById("rate").textContent = `×1 = ${baseRate.toPrecision(3)} s of run per s`;

  const legend = document.getElementById("colorbar");
  const g = legend.getContext("2d");
  const legendTitle = document.getElementById("legend").firstChild; // the text "tendon tension"
  const failureKey = document.createElement("span");
  const oneMark = document.createElement("span"); // utilisation 1 on the scale, where failure starts
  oneMark.style.position = "absolute";
  oneMark.textContent = "1";
  function drawLegend() {
    const byUse = mode === "utilisation", low = byUse ? 0 : lowT, high = byUse ? usage.high : highT;
    for (let i = 0; i < legend.height; i++) {
      const value = low + (1 - i / (legend.height - 1)) * (high - low);
      if (byUse) utilisationColor(value, rgb, 0);
      else colorOf(value, low, high, rgb, 0);
      g.fillStyle = `rgb(${255 * rgb[0]},${255 * rgb[1]},${255 * rgb[2]})`;
      g.fillRect(0, i, legend.width, 1);
    }
    legendTitle.textContent = byUse ? "member utilisation" : "tendon tension";
    document.getElementById("t-high").textContent = byUse ? high.toPrecision(3) : `${high.toPrecision(4)} N`;
    document.getElementById("t-low").textContent = byUse ? "0" : `${low.toPrecision(4)} N`;
    failureKey.style.display = byUse ? "" : "none";
    oneMark.style.display = byUse && high > 1.15 ? "" : "none"; // (apart from the top's label)
    if (byUse) oneMark.style.top = `${(1 - 1 / high) * legend.height - 8}px`;
  }
  function setColorMode(name) {
    if (name !== "tension" && !(name === "utilisation" && usage)) throw new Error(`no colour mode ${name}`);
    mode = name;
    modeBox.value = name;
    drawLegend();
    setFrame(current);
  }
  const modeBox = document.createElement("select");
  if (usage) { // the switch, the failure key: only with a design
    modeBox.id = "color-mode";
    for (const name of ["tension", "utilisation"]) modeBox.add(new Option(name, name));
    modeBox.addEventListener("change", () => setColorMode(modeBox.value));
    const label = document.createElement("label");
    label.append("colour ", modeBox);
    slider.before(label);
    failureKey.innerHTML = `<span class="key" style="border-top:5px solid ${data.colors.failure}"></span>utilisation &gt; 1 (fails)<br>`;
    legend.parentElement.querySelector("br:nth-of-type(2)").after(failureKey);
    document.getElementById("t-high").parentElement.append(oneMark);
  }
  if (contacts) { // the planes' and the contacts' key
    const key = document.createElement("span"), c = data.colors;
    key.innerHTML = `<br><span class="key" style="height:10px;border:1px solid ${c.plane_grid};` +
      `background:${c.plane};opacity:${c.plane_alpha}"></span>plane<br>` +
      `<span style="color:${c.stick}">&#9679;</span> end sticking &nbsp;` +
      `<span style="color:${c.slip}">&#9679;</span> slipping`;
    document.getElementById("legend").append(key);
  }
  drawLegend();

  controls.addEventListener("change", () => renderer.render(scene, camera));
  function resize() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    renderer.render(scene, camera);
  }
  window.addEventListener("resize", resize);
  resize();
  setFrame(0);
  requestAnimationFrame(tick);

  window.tensegrityViewer = {
    data, nFrames: F, setFrame,
    frame: () => current,
    time: () => times[current],
    play: () => { if (!playing) playButton.click(); },
    pause: () => { if (playing) playButton.click(); },
    nodePositions: (k) => Array.from(positions.subarray(k * N * 3, (k + 1) * N * 3)),
    tensions: (k) => Array.from(tensions.subarray(k * S, (k + 1) * S)),
    colorMode: () => mode,
    setColorMode, // "tension" or (with a design) "utilisation"
    // the members' utilisation in frame k, or null without a design
    utilisation: (k) => usage && {
      rods: Array.from(usage.rods.subarray(k * R, (k + 1) * R)),
      tendons: Array.from(usage.tendons.subarray(k * S, (k + 1) * S)),
    },
    // the drawn colour [r, g, b] of rod i: the rod colour, or its utilisation's
    rodColor: (i) => {
      if (!rodMesh.instanceColor) return null; // (no design: the material's colour)
      const c = rodMesh.getColorAt(i, drawnColor).getRGB({ r: 0, g: 0, b: 0 }, "srgb");
      return [c.r, c.g, c.b];
    },
    // the colour [r, g, b] (sRGB, the legend's) of tendon j in this frame, or null if it is slack
    // (dashed)
    tendonColor: (j) => (tensions[current * S + j] > 0 ? Array.from(tendonRGB(current, j)) : null),
    // the contact pairs' modes in frame k (0 free, 1 slip, 2 stick), or null without planes
    contactModes: (k) => contacts && Array.from(contacts.mode.subarray(k * contacts.n, (k + 1) * contacts.n)),
    // the ends marked in this frame: {node: [...], mode: [...]} (1 slip, 2 stick), or null
    contactEnds: () => {
      if (!contacts) return null;
      const m = contactsAt(current);
      return { node: Array.from(contactNode.subarray(0, m)), mode: Array.from(contactMode.subarray(0, m)) };
    },
    pickAt: (x, y) => { const w = pickAt(x, y); return w && member(w.kind, w.id); },
    // where the point (x, y, z) [m] is drawn: [x, y] in the page's CSS pixels, as pickAt's
    toScreen: (x, y, z) => {
      const box = renderer.domElement.getBoundingClientRect(), q = new T.Vector3(x, y, z).project(camera);
      return [box.left + 0.5 * (q.x + 1) * box.width, box.top + 0.5 * (1 - q.y) * box.height];
    },
    ready: true,
  };
})();
