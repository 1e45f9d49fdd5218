// The dashboard's study parts: the task scene in the 3D view, task and interface choice, the
// keyboard (key-down/key-up sent as they happen), the teach pendant's jog panel, the
// gripper button and the experimenter's trial controls. The server decides everything:
// the page only sends what the person did and draws the state it gets back.

// ------------------------------------------------------------------ the task scene (3D)
export function makeTaskView(THREE, arm, page) {
  const group = new THREE.Group();
  arm.scene.add(group);
  let moving = [];
  let particles = null; // one mesh of n low-poly spheres: its vertices move each frame
  let template = null; // one sphere's vertex positions

  function geometryOf(shape) {
    const s = shape.size;
    if (shape.type === "mesh") {
      const g = new THREE.BufferGeometry();
      g.setAttribute("position", new THREE.Float32BufferAttribute(shape.vertices, 3));
      g.setIndex(shape.faces);
      const flat = g.toNonIndexed(); // one normal per face: crisp edges
      flat.computeVertexNormals();
      return flat;
    }
    if (shape.type === "box") return new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
    if (shape.type === "sphere") return new THREE.SphereGeometry(s[0], 16, 12);
    const g = shape.type === "capsule"
      ? new THREE.CapsuleGeometry(s[0], 2 * s[1], 6, 16)
      : new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 24);
    g.rotateX(Math.PI / 2); // three's run along y, MuJoCo's along z
    return g;
  }
  function meshOf(shape) {
    const [r, g, b, a] = shape.rgba;
    const material = new THREE.MeshStandardMaterial({ color: new THREE.Color(r, g, b), transparent: a < 1, opacity: a, roughness: 0.7 });
    const mesh = new THREE.Mesh(geometryOf(shape), material);
    mesh.name = shape.name;
    return mesh;
  }
  function place(mesh, p) { mesh.position.set(p[0], p[1], p[2]); mesh.quaternion.set(p[4], p[5], p[6], p[3]); }

  function build(description) {
    while (group.children.length) group.remove(group.children[0]);
    moving = []; particles = null; template = null;
    page.task = description ? { name: description.name, particles: 0, moving: 0 } : null;
    for (const m of arm.meshes) m.visible = m.name !== "skin_patch" && !(description && description.hide.includes(m.name));
    arm.grid.visible = !description; // the table top lies at z = 0
    if (!description) return;
    for (const shape of description.fixed) { const mesh = meshOf(shape); place(mesh, shape.pose); group.add(mesh); }
    for (const shape of description.moving) { const mesh = meshOf(shape); moving.push(mesh); group.add(mesh); }
    const n = description.particles.count;
    if (n) {
      const sphere = new THREE.SphereGeometry(description.particles.radius, 6, 4);
      template = sphere.attributes.position.array;
      const nv = template.length / 3, index = sphere.index.array;
      const positions = new Float32Array(template.length * n), normals = new Float32Array(template.length * n);
      const indices = [];
      for (let k = 0; k < n; k++) {
        normals.set(sphere.attributes.normal.array, k * template.length);
        for (const i of index) indices.push(i + k * nv);
      }
      const g = new THREE.BufferGeometry();
      g.setAttribute("position", new THREE.Float32BufferAttribute(positions, 3));
      g.setAttribute("normal", new THREE.Float32BufferAttribute(normals, 3));
      g.setIndex(indices);
      const [r, gg, b] = description.particles.rgba;
      particles = new THREE.Mesh(g, new THREE.MeshStandardMaterial({ color: new THREE.Color(r, gg, b), roughness: 0.4 }));
      particles.name = "particles"; particles.frustumCulled = false;
      group.add(particles);
    }
    page.task.moving = moving.length;
  }

  function update(task) {
    if (!task || !page.task) return;
    task.geoms.forEach((p, k) => { if (moving[k]) place(moving[k], p); });
    if (particles && template) {
      const out = particles.geometry.attributes.position, array = out.array, centres = task.particles;
      const per = template.length, n = centres.length / 3;
      for (let k = 0; k < n; k++) {
        const x = centres[3 * k], y = centres[3 * k + 1], z = centres[3 * k + 2], base = k * per;
        for (let i = 0; i < per; i += 3) {
          array[base + i] = template[i] + x; array[base + i + 1] = template[i + 1] + y; array[base + i + 2] = template[i + 2] + z;
        }
      }
      out.needsUpdate = true;
      page.task.particles = n;
    }
    page.task.state = task.state;
  }
  return { build, update };
}

// ------------------------------------------------------------------ panels and keys
export function setupStudy({ $, page, send, command }) {
  // A choice the person just made is not undone by a state that left the server before the
  // server took it up (a busy session publishes late): the control keeps the chosen value
  // until the state agrees, or for 5 s.
  const chosen = new Map(); // element id -> {value, until}
  for (const id of ["interface", "task", "jog-frame", "jog-step", "jog-speed"]) {
    $(id).addEventListener("change", () => chosen.set(id, { value: String($(id).value), until: performance.now() + 5000 }));
  }
  function show(id, value) { // the server's value, unless the person's newer choice stands
    const mine = chosen.get(id);
    if (mine && String(value) !== mine.value && performance.now() < mine.until) return false;
    chosen.delete(id);
    if (document.activeElement !== $(id)) $(id).value = value;
    return true;
  }
  const keysDown = new Set();
  let jogHeld = false;
  let keyNames = new Set();
  const typing = () => { const el = document.activeElement; return el && (el.tagName === "TEXTAREA" || (el.tagName === "INPUT" && !["range", "checkbox", "button"].includes(el.type))); };
  const interfaceIs = (name) => page.state && page.state.teleop && page.state.teleop.interface === name;

  window.addEventListener("keydown", (event) => {
    const key = event.key.length === 1 ? event.key.toLowerCase() : "";
    if (!keyNames.has(key) || !interfaceIs("keyboard") || typing() || event.ctrlKey || event.metaKey || event.altKey) return;
    event.preventDefault();
    if (event.repeat || keysDown.has(key)) return; // auto-repeat is no new press
    if (key !== "g") keysDown.add(key);
    send({ type: "key", key, down: true });
    if (key === "g") send({ type: "key", key, down: false });
  });
  window.addEventListener("keyup", (event) => {
    const key = event.key.length === 1 ? event.key.toLowerCase() : "";
    if (!keysDown.delete(key)) return;
    send({ type: "key", key, down: false });
  });
  function releaseAll() {
    if (keysDown.size) { keysDown.clear(); send({ type: "key", release_all: true }); }
    if (jogHeld) { jogHeld = false; send({ type: "pendant", op: "release" }); }
  }
  window.addEventListener("blur", releaseAll);
  document.addEventListener("visibilitychange", () => { if (document.hidden) releaseAll(); });
  setInterval(() => { if (keysDown.size || jogHeld) send({ type: "hold" }); }, 250); // hold-to-run heartbeat
  page.keysDown = keysDown;

  const pendant = (op, extra = {}) => send({ type: "pendant", op, ...extra });
  $("task").addEventListener("change", () => command("task", { task: $("task").value }));
  $("interface").addEventListener("change", () => { releaseAll(); command("interface", { interface: $("interface").value }); });
  $("gripper").addEventListener("click", () => command("gripper"));
  $("jog-frame").addEventListener("change", () => pendant("frame", { value: $("jog-frame").value }));
  $("jog-step").addEventListener("change", () => { const v = $("jog-step").value; pendant("step", { value: v === "off" ? null : Number(v) }); });
  $("jog-speed").addEventListener("input", () => { $("jog-speed-value").textContent = `${$("jog-speed").value}%`; });
  $("jog-speed").addEventListener("change", () => pendant("speed", { value: Number($("jog-speed").value) }));
  $("jog-initial").addEventListener("click", () => pendant("go_to", { pose: "initial" }));
  $("jog-home").addEventListener("click", () => pendant("go_to", { pose: "home" }));
  $("jog-gripper").addEventListener("click", () => pendant("gripper"));
  for (const [id, op] of [["trial-start", "start"], ["trial-success", "success"], ["trial-give-up", "give_up"], ["trial-abort", "abort"]]) {
    $(id).addEventListener("click", () => command("trial", { op, participant: $("participant").value.trim() }));
  }

  let axesShown = "";
  function buildAxes(panel) {
    const key = `${panel.frame}:${panel.axes.join(",")}`;
    if (key === axesShown) return;
    axesShown = key;
    const box = $("jog-axes");
    box.innerHTML = "";
    for (const axis of panel.axes) {
      for (const sign of [-1, 1]) {
        const button = document.createElement("button");
        button.textContent = `${panel.frame === "joint" ? `J${axis}` : axis} ${sign > 0 ? "+" : "−"}`;
        button.dataset.axis = String(axis); button.dataset.sign = String(sign);
        button.addEventListener("pointerdown", (event) => {
          event.preventDefault();
          button.setPointerCapture(event.pointerId);
          pendant("press", { axis: panel.frame === "joint" ? Number(axis) : axis, sign });
          jogHeld = $("jog-step").value === "off";
        });
        const up = () => { if (jogHeld) { jogHeld = false; pendant("release"); } };
        for (const kind of ["pointerup", "pointerleave", "pointercancel", "lostpointercapture"]) button.addEventListener(kind, up);
        box.appendChild(button);
      }
    }
  }

  function onScene(message) {
    const fill = (select, values, chosen) => {
      if (select.dataset.values !== values.join()) {
        select.innerHTML = values.map((v) => `<option value="${v}">${v.replace("_", " ")}</option>`).join("");
        select.dataset.values = values.join();
      }
      select.value = chosen;
    };
    fill($("task"), message.tasks || ["none"], message.task ? message.task.name : "none");
    fill($("interface"), message.interfaces || ["skin"], $("interface").value || "skin");
    keyNames = new Set((message.keys || []).map((row) => row.key));
    $("keymap").innerHTML = (message.keys || []).map((row) => `<span><b>${row.key.toUpperCase()}</b> ${row.action}</span>`).join("");
    $("study-folder").textContent = message.study ? `study: ${message.study}` : "no study folder (--study DIR)";
  }

  function update(state) {
    const teleop = state.teleop;
    if (!teleop) return;
    show("interface", teleop.interface);
    $("commands").textContent = `commands ${teleop.commands} · gripper ${teleop.gripper_closed ? "closed" : "open"}${teleop.held ? ` · ${teleop.held}` : ""}`;
    $("commands").dataset.count = String(teleop.commands);
    $("keymap").hidden = teleop.interface !== "keyboard";
    $("pendant").hidden = teleop.interface !== "pendant";
    if (teleop.pendant) {
      const panel = teleop.pendant;
      show("jog-frame", panel.frame);
      show("jog-step", panel.step_size === null ? "off" : String(panel.step_size));
      if (show("jog-speed", panel.speed_percent)) $("jog-speed-value").textContent = `${panel.speed_percent}%`;
      buildAxes(panel);
    }
    const task = state.task;
    show("task", task ? task.name : "none");
    const s = task && task.state;
    $("task-state").textContent = !s ? "" : s.task === "pour"
      ? `in cup ${s.in_cup} · delivered ${s.delivered} · spilled ${s.spilled} of ${s.total}${s.succeeded ? " · DONE" : ""}`
      : `seated ${s.seated} of ${s.total}${s.succeeded ? " · DONE" : ""}`;
    const study = state.study;
    if (!study) return;
    for (const id of ["trial-success", "trial-give-up", "trial-abort"]) $(id).disabled = !study.running;
    $("trial-start").disabled = study.running || !study.folder;
    if (study.running) {
      const limit = study.time_limit_s ? ` / ${study.time_limit_s.toFixed(0)} s` : "";
      $("trial-timer").textContent = `${study.elapsed_s.toFixed(1)} s${limit}${study.started ? "" : " (waits for the first command)"}`;
      $("trial-status").textContent = `${study.participant} · ${study.task} · ${study.interface} · trial ${study.trial}`;
    } else {
      $("trial-timer").textContent = "-";
      const last = study.last;
      $("trial-status").textContent = last ? `last: ${last.outcome}, ${last.duration_s} s, ${last.commands} commands` : "";
    }
  }
  // ---------------------------------------------------------------- questionnaires
  // After a condition the participant answers the study's questionnaires (NASA-TLX raw,
  // SUS) here; the server checks and scores them into questionnaires.csv.
  let forms = {};
  let about = null; // {participant, task, interface} the answers are about
  function buildForms(next) {
    if (JSON.stringify(next) === JSON.stringify(forms)) return;
    forms = next || {};
    $("q-tlx").innerHTML = (forms.nasa_tlx || []).map((item) =>
      `<div class="item"><b>${item.label}</b> <span class="mono" id="q-tlx-${item.key}-value">50</span>` +
      `<p>${item.question}</p><input type="range" id="q-tlx-${item.key}" min="0" max="100" step="5" value="50"></div>`).join("");
    $("q-sus").innerHTML = (forms.sus || []).map((text, i) =>
      `<div class="item"><p>${i + 1}. ${text}</p><div class="likert">strongly disagree` +
      [1, 2, 3, 4, 5].map((v) => `<label><input type="radio" name="q-sus-${i + 1}" value="${v}">${v}</label>`).join("") +
      ` strongly agree</div></div>`).join("");
    for (const item of forms.nasa_tlx || []) {
      $(`q-tlx-${item.key}`).addEventListener("input", (e) => { $(`q-tlx-${item.key}-value`).textContent = e.target.value; });
    }
    $("q-open").hidden = !forms.nasa_tlx && !forms.sus;
  }
  function openForm() {
    const participant = $("participant").value.trim();
    about = { participant, task: $("task").value === "none" ? "" : $("task").value, interface: $("interface").value };
    $("q-about").textContent = `${participant || "(no participant)"} · ${about.interface}${about.task ? ` · ${about.task}` : ""}`;
    $("questionnaire").hidden = false;
    $("q-prompt").textContent = "";
  }
  $("q-open").addEventListener("click", openForm);
  $("q-cancel").addEventListener("click", () => { $("questionnaire").hidden = true; });
  $("questionnaire").addEventListener("submit", (event) => {
    event.preventDefault();
    const tlx = forms.nasa_tlx ? forms.nasa_tlx.map((item) => Number($(`q-tlx-${item.key}`).value)) : null;
    let sus = null;
    if (forms.sus) {
      sus = forms.sus.map((_, i) => { const c = document.querySelector(`input[name="q-sus-${i + 1}"]:checked`); return c ? Number(c.value) : null; });
      if (sus.includes(null)) { $("q-prompt").textContent = "answer every SUS statement"; return; }
    }
    command("questionnaire", { ...about, tlx, sus });
    $("questionnaire").hidden = true;
    $("questionnaire").reset();
    for (const item of forms.nasa_tlx || []) $(`q-tlx-${item.key}-value`).textContent = "50";
  });
  // ---------------------------------------------------------------- the plan
  // The participant's next condition in the study's counterbalanced plan (plan.py);
  // "Use" chooses its task and interface.
  let planTimer = null;
  $("participant").addEventListener("input", () => {
    clearTimeout(planTimer);
    planTimer = setTimeout(() => command("plan", { participant: $("participant").value.trim() }), 300);
  });
  $("plan-use").addEventListener("click", () => {
    const plan = page.state && page.state.study && page.state.study.plan;
    if (!plan || plan.done) return;
    if ($("task").value !== plan.task) command("task", { task: plan.task });
    command("interface", { interface: plan.interface });
  });
  function showPlan(study) {
    const plan = study.plan;
    $("plan-use").hidden = !plan || plan.done || study.running;
    if (!plan) { $("plan").textContent = ""; return; }
    $("plan").textContent = plan.done
      ? `plan: ${plan.participant} has done all ${plan.steps} conditions`
      : `plan: step ${plan.step} of ${plan.steps} · ${plan.task.replace("_", " ")} with ${plan.interface.replace("_", " ")} · trial ${plan.trial} of ${plan.trials}`;
  }

  let lastTrial = null;
  function promptAfterTrial(study) { // a trial ended: remind the experimenter of the questionnaire
    const key = study.last ? study.last.folder : null;
    if (key && key !== lastTrial && !$("q-open").hidden) $("q-prompt").textContent = "after the condition's last trial: questionnaire";
    lastTrial = key;
  }

  const baseScene = onScene;
  const baseUpdate = update;
  return {
    onScene(message) { baseScene(message); buildForms(message.questionnaires); },
    update(state) { baseUpdate(state); if (state.study) { promptAfterTrial(state.study); showPlan(state.study); } },
  };
}
