// The dashboard's "Record & adapt" panel (server side: adapt_flow.py, adapt_api.py).
// The person enters their name (and, if they like, the gestures and trials per gesture),
// records on the skin the dashboard runs with a prompt, a countdown and the live heatmap,
// watches the adaptation's progress, reads the before/after table and puts the adapted
// model in use (or goes back). The page only asks (POST /api/adapt/<op>) and draws the
// panel's state that every snapshot carries (state.adapt): the server decides everything.

export function setupAdapt({ $, colour, token }) {
  const panel = $("adapt");
  let builtGestures = "";
  let lastError = "";

  async function post(op, body = {}) {
    const url = `api/adapt/${op}${token ? `?token=${encodeURIComponent(token)}` : ""}`;
    try {
      const reply = await fetch(url, {
        method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
      });
      const data = await reply.json().catch(() => ({}));
      lastError = reply.ok ? "" : (data.error || `refused (${reply.status})`);
    } catch (error) {
      lastError = `the dashboard did not answer: ${error}`;
    }
    $("adapt-error").textContent = lastError;
  }

  function openPanel(open) { panel.hidden = !open; }

  function buildGestures(gestures) {
    const key = gestures.join(",");
    if (key === builtGestures) return;
    builtGestures = key;
    const box = $("adapt-gestures");
    box.innerHTML = "";
    for (const name of gestures) {
      const label = document.createElement("label");
      label.className = "inline";
      const input = document.createElement("input");
      input.type = "checkbox"; input.checked = true; input.value = name;
      label.append(input, ` ${name}`);
      box.appendChild(label);
    }
  }

  function chosenGestures() {
    const boxes = [...$("adapt-gestures").querySelectorAll("input")];
    const chosen = boxes.filter((b) => b.checked).map((b) => b.value);
    return chosen.length === boxes.length ? null : chosen; // null: all the model's gestures
  }

  function estimate(adapt) { // minutes of recording: every trial's countdown and time to perform
    const gestures = chosenGestures() || adapt.gestures;
    const trials = Number($("adapt-trials").value) || adapt.defaults.trials;
    const count = gestures.length * trials + adapt.defaults.invalid_trials;
    const minutes = Math.ceil((count * adapt.defaults.trial_seconds) / 60);
    $("adapt-estimate").textContent = `${count} trials, about ${minutes} min of recording, then a few minutes of adapting`;
  }

  function drawHeat(skin) {
    const canvas = $("adapt-heat");
    const { rows, cols } = skin;
    const width = canvas.clientWidth || 240;
    const height = Math.round((width * rows * skin.row_pitch_mm) / (cols * skin.col_pitch_mm));
    if (canvas.width !== width || canvas.height !== height) { canvas.width = width; canvas.height = height; }
    const ctx = canvas.getContext("2d");
    const cw = width / cols, ch = height / rows;
    for (let r = 0; r < rows; r++) {
      for (let c = 0; c < cols; c++) {
        ctx.fillStyle = colour(Math.sqrt(Math.max(0, skin.signal[r * cols + c]) / skin.full_scale));
        ctx.fillRect(c * cw, r * ch, cw + 0.5, ch + 0.5);
      }
    }
    ctx.strokeStyle = "#7ee0ff"; ctx.lineWidth = 2;
    for (const contact of skin.contacts) {
      ctx.beginPath();
      ctx.arc((contact.col + 0.5) * cw, (contact.row + 0.5) * ch, Math.max(4, Math.sqrt(contact.size) * cw * 0.55), 0, 2 * Math.PI);
      ctx.stroke();
    }
  }

  function showPrompt(prompt) {
    const what = $("adapt-what"), count = $("adapt-count");
    if (!prompt || prompt.phase === "calibrating") {
      $("adapt-trial").textContent = "calibrating";
      what.textContent = "Keep your hands off the skin";
      what.className = "adapt-what calibrating";
      $("adapt-hint").textContent = "";
      count.textContent = "";
      return;
    }
    $("adapt-trial").textContent = `trial ${prompt.number} of ${prompt.total}`;
    what.textContent = prompt.what;
    what.className = `adapt-what ${prompt.phase}`;
    $("adapt-hint").textContent = prompt.hint || "";
    count.textContent = prompt.phase === "countdown"
      ? `get ready… ${prompt.seconds_left.toFixed(1)} s`
      : `NOW · ${prompt.seconds_left.toFixed(1)} s left`;
  }

  function cell(value, digits = 3) { return value === null || value === undefined ? "–" : Number(value).toFixed(digits); }

  function showResult(adapt) {
    const summary = adapt.summary;
    $("adapt-verdict").textContent = adapt.verdict || adapt.message;
    $("adapt-verdict").className = adapt.phase === "done" ? "verdict ok" : "verdict bad";
    const figures = $("adapt-figures"), classes = $("adapt-classes");
    const key = JSON.stringify(summary);
    if (figures.dataset.key === key) return;
    figures.dataset.key = key;
    fill(figures, ["held-out trials", "before", "adapted"], []);
    fill(classes, ["class", "trials", "recall before", "adapted"], []);
    if (!summary) return;
    fill(figures, ["held-out trials", "before", "adapted"], summary.figures.map((row) => {
      const digits = row.name.includes("ms") ? 0 : (row.name.includes("min") ? 2 : 3);
      return [row.name, cell(row.before, digits), cell(row.after, digits)];
    }));
    fill(classes, ["class", "trials", "recall before", "adapted"], summary.classes.map((row) =>
      [row.name, row.events ?? "–", cell(row.before, 2), cell(row.after, 2)]));
  }

  function fill(table, head, rows) { // text only: nothing from the server becomes markup
    table.replaceChildren();
    const top = table.createTHead().insertRow();
    for (const name of head) { const th = document.createElement("th"); th.textContent = name; top.appendChild(th); }
    const body = table.createTBody();
    for (const values of rows) {
      const row = body.insertRow();
      for (const value of values) row.insertCell().textContent = String(value);
    }
  }

  function update(state) {
    const adapt = state.adapt;
    if (!adapt) return;
    const busy = adapt.phase === "recording" || adapt.phase === "adapting";
    if (busy && panel.hidden) openPanel(true); // a reloaded page finds the flow running
    $("adapt-open").textContent = busy ? `Record & adapt: ${adapt.phase}…` : "Record & adapt";
    $("adapt-open").classList.toggle("active", busy);
    if (panel.hidden) return;
    buildGestures(adapt.gestures);
    $("adapt-torch").hidden = !adapt.torch;
    $("adapt-torch").textContent = adapt.torch;
    $("adapt-perform-label").hidden = !adapt.defaults.simulated;
    const finished = ["done", "refused", "failed", "saved"].includes(adapt.phase);
    $("adapt-form").hidden = busy || finished;
    $("adapt-record").hidden = adapt.phase !== "recording";
    $("adapt-run").hidden = adapt.phase !== "adapting";
    $("adapt-result").hidden = !(adapt.phase === "done" || adapt.phase === "refused");
    $("adapt-again").hidden = !finished;
    $("adapt-message").textContent = adapt.verdict ? "" : adapt.message; // the verdict says it
    const inUse = adapt.model.in_use;
    $("adapt-model").textContent = `recogniser in use: ${inUse || "the model the dashboard started with"}`;
    $("adapt-revert").hidden = !adapt.model.can_revert;
    $("adapt-use").hidden = !(adapt.phase === "done" || adapt.phase === "refused");
    $("adapt-use").disabled = !adapt.model.can_use;
    $("adapt-use").title = adapt.phase === "refused" ? "adapt refused this model: it scored worse than the one in use" : "";
    if (!$("adapt-form").hidden) estimate(adapt);
    if (adapt.phase === "recording") {
      showPrompt(adapt.prompt);
      drawHeat(state.skin);
    } else if (adapt.phase === "adapting" && adapt.progress) {
      const p = adapt.progress;
      $("adapt-stage").textContent = `${p.stage}${p.total ? ` · ${p.done} of ${p.total}` : ""} · ${Math.round(p.seconds)} s`;
      $("adapt-progress").max = Math.max(1, p.total);
      $("adapt-progress").value = Math.min(p.done, Math.max(1, p.total));
      $("adapt-note").textContent = [...p.stages.slice(0, -1).map((s) => `${s} ✓`), p.note].filter(Boolean).join(" · ");
    } else if (!$("adapt-result").hidden) {
      showResult(adapt);
    }
  }

  $("adapt-open").addEventListener("click", () => openPanel(panel.hidden));
  $("adapt-close").addEventListener("click", () => openPanel(false));
  $("adapt-form").addEventListener("submit", (event) => {
    event.preventDefault();
    const body = { name: $("adapt-name").value.trim(), trials: Number($("adapt-trials").value) };
    const gestures = chosenGestures();
    if (gestures) body.gestures = gestures;
    if (!$("adapt-perform-label").hidden) body.perform = $("adapt-perform").checked;
    post("record", body);
  });
  $("adapt-cancel-record").addEventListener("click", () => post("cancel"));
  $("adapt-cancel-run").addEventListener("click", () => post("cancel"));
  $("adapt-use").addEventListener("click", () => post("use"));
  $("adapt-revert").addEventListener("click", () => post("revert"));
  $("adapt-again").addEventListener("click", () => post("reset"));
  return { update, post };
}
