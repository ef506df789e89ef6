// The curation page: draws the session's state (/api/state, polled every second)
// and sends the person's answers. The server checks everything; this script only shows.
"use strict";

const CSRF = document.querySelector('meta[name="csrf-token"]').content;
const POLL_MS = 1000;
let state = null;
let shownQuestion = null; // the id of the question whose form is on the page
let shownHistory = "";
let shownTraining = "";

// -- small helpers ---------------------------------------------------------------

function el(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attributes)) {
    if (value === null || value === undefined || value === false) continue;
    if (key === "class") node.className = value;
    else if (key === "text") node.textContent = value;
    else if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
    else node.setAttribute(key, value === true ? "" : value);
  }
  for (const child of children.flat()) {
    if (child === null || child === undefined) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

// A value the server sent as null (Python's None) shows as a dash, never as "null" or "None".
const missing = (value) => value === null || value === undefined || Number.isNaN(value);
const fixed = (value, digits = 2) => (missing(value) ? "–" : Number(value).toFixed(digits));
const signed = (value, digits = 2) => (missing(value) ? "–" : (value >= 0 ? "+" : "") + fixed(value, digits));
const count = (n) => (missing(n) ? "–" : n >= 1e6 ? `${fixed(n / 1e6, 2)} M` : n >= 1e3 ? `${fixed(n / 1e3, 1)} k` : `${n}`);

function duration(seconds) {
  if (seconds === null || seconds === undefined) return "–";
  seconds = Math.round(seconds);
  if (seconds < 60) return `${seconds} s`;
  const minutes = Math.floor(seconds / 60);
  if (minutes < 60) return `${minutes} min ${seconds % 60} s`;
  return `${Math.floor(minutes / 60)} h ${minutes % 60} min`;
}

function previewUrl(maze) {
  return `/api/maze.png?string=${encodeURIComponent(maze)}`;
}

async function post(path, body) {
  const response = await fetch(path, {
    method: "POST",
    headers: { "Content-Type": "application/json", "X-CSRF-Token": CSRF },
    body: JSON.stringify(body),
  });
  let data = {};
  try {
    data = await response.json();
  } catch (_) {
    data = { error: `the server answered ${response.status}` };
  }
  return { ok: response.ok, status: response.status, data };
}

// -- the state loop ----------------------------------------------------------------

async function poll() {
  let next = null;
  try {
    const response = await fetch("/api/state", { cache: "no-store" });
    if (response.status === 403) {
      showLost("This page needs the address with its token that amaze-curate printed.");
      return;
    }
    next = await response.json();
  } catch (_) {
    showLost("The server does not answer. Restart it with amaze-curate --resume and reload.");
  }
  if (next) {
    const changed = !state || next.version !== state.version;
    state = next;
    if (changed) draw();
    else tick();
  }
  setTimeout(poll, POLL_MS);
}

function showLost(message) {
  document.getElementById("phase").textContent = "disconnected";
  document.getElementById("phase").className = "badge failed";
  let banner = document.getElementById("lost");
  if (!banner) {
    banner = el("p", { id: "lost", class: "error banner" });
    document.querySelector("main").prepend(banner);
  }
  banner.textContent = message;
}

function draw() {
  const lost = document.getElementById("lost");
  if (lost) lost.remove();
  drawHeader();
  const view = document.getElementById("view");
  const question = state.question;
  if (state.phase === "question" && question) {
    if (shownQuestion !== question.id) {
      shownQuestion = question.id;
      shownTraining = "";
      view.replaceChildren(question.kind === "select" ? selectView(question) : generateView(question));
      window.scrollTo(0, 0); // a new question: its top first
    }
  } else {
    shownQuestion = null;
    if (state.phase === "finished") view.replaceChildren(finalView());
    else if (state.phase === "failed") view.replaceChildren(failedView());
    else drawTraining(view);
  }
  drawHistory();
  tick();
}

function tick() {
  // What changes with time alone: how long a question has waited.
  const waiting = document.getElementById("waiting");
  if (waiting && state.question) waiting.textContent = `waiting ${duration(state.question.waiting)}`;
}

function drawHeader() {
  const run = state.run;
  document.getElementById("run-description").textContent =
    `${run.algo.toUpperCase()}, robot ${run.robot}, ${run.stages} stages × ${run.branches} branches, ` +
    `${count(run.budget_steps)} env steps, seed ${run.seed}` +
    (run.target ? ` · target ${run.target}` : "") +
    (run.advisor ? ` · advisor ${run.advisor}` : "");
  const phase = document.getElementById("phase");
  const names = {
    starting: "starting",
    training: "training",
    question: "your turn",
    finished: "finished",
    failed: "failed",
  };
  phase.textContent = names[state.phase] || state.phase;
  phase.className = `badge ${state.phase}`;
  const training = state.training;
  const fraction = training.budget_steps ? Math.min(1, training.steps / training.budget_steps) : 0;
  document.getElementById("overall-bar").style.width = `${(100 * fraction).toFixed(1)}%`;
  // While a question waits, nothing trains: the time left is the person's.
  const eta = state.phase === "finished" || state.phase === "failed" ? ""
    : state.phase === "question" ? " · waiting for you"
      : ` · training left ≈ ${duration(training.eta_seconds)}`;
  document.getElementById("overall-text").textContent =
    `${count(training.steps)} / ${count(training.budget_steps)} steps${eta}`;
}

// -- training ------------------------------------------------------------------

function drawTraining(view) {
  const training = state.training;
  const key = JSON.stringify([state.phase, training.stage, training.branches]);
  if (key === shownTraining) return;
  shownTraining = key;
  if (training.stage === null) {
    view.replaceChildren(el("h2", { text: "Starting the run…" }),
      el("p", { class: "muted", text: "The first agent is being built." }));
    return;
  }
  const stageMazes = stageMazesOf(training.stage);
  const rows = training.branches.map((b) => {
    const fraction = b.budget_steps ? Math.min(1, b.steps / b.budget_steps) : b.done ? 1 : 0;
    const maze = stageMazes[b.branch];
    return el("div", { class: "branch-progress", "data-branch": b.branch },
      maze ? el("img", { class: "thumb", src: previewUrl(maze), alt: `maze of branch ${b.branch}` }) : null,
      el("div", { class: "grow" },
        el("div", {}, el("strong", { text: `Branch ${b.branch}` }),
          maze ? el("code", { class: "maze-string", text: ` ${maze}` }) : null),
        el("div", { class: "bar" }, el("div", { style: `width:${(100 * fraction).toFixed(1)}%` })),
        el("div", { class: "muted" },
          b.done ? `done: ${count(b.steps)} steps`
            : `${count(b.steps)} / ${count(b.budget_steps)} steps · ≈ ${duration(b.eta_seconds)} left`)));
  });
  const rate = training.steps_per_second ? ` at about ${count(training.steps_per_second)} steps/s` : "";
  view.replaceChildren(
    el("h2", { id: "training", text: `Training stage ${training.stage}` }),
    el("p", { class: "muted", text: `Each branch is a copy of the chosen agent, trained on its own maze in its 4 rotations${rate}. The next question comes when all are done.` }),
    el("div", { class: "progress-list" }, rows));
}

function stageMazesOf(stage) {
  const decision = state.history.decisions.find((d) => d.kind === "generate" && d.stage === stage);
  return decision ? decision.mazes : [];
}

// -- the advisor's proposal -----------------------------------------------------------

const CRITERIA_LABELS = {
  validation_success_rate: "success, its validation mazes",
  validation_normalized_reward: "R̄, its validation mazes",
  difficulty_reached: "difficulty reached",
  extinct: "rejected (no goal on its maze)",
  success_rate: "success, its maze",
  normalized_reward: "R̄, its maze",
  overall_success_rate: "success, the stage's mazes",
  overall_normalized_reward: "R̄, the stage's mazes",
  env_steps: "env steps",
  converged: "converged",
};

function criterion(value) {
  if (typeof value === "boolean") return value ? "yes" : "no";
  if (typeof value === "number") return Number.isInteger(value) ? `${value}` : fixed(value, 3);
  return value === null || value === undefined ? "–" : `${value}`;
}

function criteriaTable(advice) {
  const keys = [];
  advice.criteria.forEach((row) => Object.keys(row).forEach((key) => {
    if (key !== "branch" && !keys.includes(key)) keys.push(key);
  }));
  return el("table", { class: "figures criteria" },
    el("tr", {}, el("th", { text: "branch" }), keys.map((key) => el("th", { text: CRITERIA_LABELS[key] || key }))),
    advice.criteria.map((row) => el("tr", { class: row.branch === advice.choice ? "proposed" : "" },
      el("td", { text: `${row.branch}${row.branch === advice.choice ? " ★" : ""}` }),
      keys.map((key) => el("td", { text: criterion(row[key]) })))));
}

function selectAdvice(question) {
  const advice = question.advice;
  if (!advice) return null;
  return el("section", { id: "advice", class: "card advice" },
    el("h3", {}, el("span", { class: "pill advisor", text: "advisor" }),
      ` ${advice.advisor} proposes branch ${advice.choice}`),
    el("p", { class: "muted", text:
      `Its pick among the Pareto front (branches ${advice.front.join(", ")}) of the criteria below; ` +
      "take it, or choose another branch below: either way the proposal and your choice are recorded." }),
    criteriaTable(advice),
    el("button", { id: "take-proposal", class: "primary",
      onclick: (event) => choose(question, advice.choice, event.target, "Take it: choose branch " + advice.choice) },
    `Take it: choose branch ${advice.choice}`));
}

function operators(names) {
  // The genome operators in the order applied, a repeated one counted: "size_up, seed ×2".
  const counts = new Map();
  names.forEach((name) => counts.set(name, (counts.get(name) || 0) + 1));
  return [...counts].map(([name, n]) => (n > 1 ? `${name} ×${n}` : name)).join(", ");
}

function generateAdvice(question) {
  const advice = question.advice;
  if (!advice) return null;
  const mazes = advice.reasons.map((reason, i) => el("figure", { class: "proposed-maze", "data-index": i },
    el("img", { class: "thumb", src: previewUrl(reason.maze), alt: reason.maze, title: reason.maze }),
    el("figcaption", {},
      el("div", {}, el("strong", { text: `maze ${i + 1} ` }), el("code", { class: "maze-string", text: reason.maze })),
      el("ul", { class: "reasons" },
        el("li", { text: reason.operators.length ? `made by ${operators(reason.operators)}` : "the agent's last maze, unchanged" }),
        el("li", { text: `distance to the target ${fixed(reason.distance, 2)}` }),
        el("li", { text: `expected difficulty ${fixed(reason.difficulty, 2)}` })),
      el("button", { type: "button", id: `use-proposal-${i}`, class: "small",
        onclick: () => useProposed(question, i, reason.maze) }, `edit it as maze ${i + 1}`))));
  return el("section", { id: "advice", class: "card advice" },
    el("h3", {}, el("span", { class: "pill advisor", text: "advisor" }),
      ` ${advice.advisor} proposes ${advice.mazes.length} maze${advice.mazes.length > 1 ? "s" : ""}`),
    el("p", { class: "muted", text: "The editors below start from them: take them as they are, edit them, or design your own; " +
      "the proposal and which of its mazes you kept are recorded." }),
    el("div", { class: "proposed-mazes" }, mazes),
    el("button", { id: "take-proposal", class: "primary", onclick: () => takeMazes(question) },
      `Take the advisor's ${advice.mazes.length} maze${advice.mazes.length > 1 ? "s" : ""}`));
}

async function takeMazes(question) {
  const button = document.getElementById("take-proposal");
  document.querySelectorAll("#take-proposal, #submit-mazes").forEach((b) => (b.disabled = true));
  button.textContent = "Sending…";
  const { ok, status, data } = await post("/api/answer", { question: question.id, answer: question.advice.mazes });
  if (ok) {
    button.textContent = "Sent: training starts…";
    return;
  }
  document.getElementById("answer-error").textContent = data.error;
  button.disabled = false;
  button.textContent = `Take the advisor's ${question.advice.mazes.length} mazes`;
  if (status === 409) shownQuestion = null;
  else refreshSubmit(question);
}

function useProposed(question, index, maze) {
  const input = document.getElementById(`maze-string-${index}`);
  if (!input) return;
  input.value = maze;
  changed(question, index);
  update(question, index, {});
}

// -- choosing an agent -----------------------------------------------------------

function selectView(question) {
  const final = question.stage >= state.run.stages;
  // The branches were trained in the stage before the question's: the page names that one.
  const trained = question.stage - 1;
  const cards = question.candidates.map((c) => candidateCard(question, c));
  return el("div", {},
    el("h2", { text: final ? `Choose the final agent (stage ${trained})` : `Stage ${trained}: choose the agent that goes on` }),
    el("p", { class: "muted" },
      final ? "The chosen agent is the run's result: it is then tested on the standard evaluation suite. "
        : "Its copies train on the mazes you design next. Each agent is shown on every maze of the stage. ",
      "Success: the goal reached (a dot per start corner, green when reached); R̄: the paper's normalized reward, 1 on the shortest path; ",
      "the target's family: mazes of the target's kind none of the agents trained on. ",
      el("span", { id: "waiting" })),
    selectAdvice(question),
    el("div", { class: "candidates" }, cards),
    el("p", { id: "answer-error", class: "error", role: "alert" }));
}

function familyRows(family) {
  if (!family) return [];
  return [
    el("tr", { class: "family" }, el("th", { text: `success, the target's family (${family.mazes} mazes)` }),
      el("td", { class: "family-success", text: fixed(family.success_rate) })),
    el("tr", { class: "family" }, el("th", { text: "R̄, the target's family" }),
      el("td", { text: signed(family.normalized_reward, 3) })),
  ];
}

function candidateCard(question, c) {
  const episodes = c.results.map((r) => episodeTile(question.stage - 1, c.branch, r));
  const proposed = question.advice && question.advice.choice === c.branch;
  return el("article", { class: proposed ? "candidate card proposed" : "candidate card", "data-branch": c.branch },
    el("header", {},
      el("h3", { text: `Branch ${c.branch}` }),
      proposed ? el("span", { class: "pill advisor", text: `${question.advice.advisor}'s pick` }) : null,
      el("span", { class: c.success_rate === 1 ? "pill good" : "pill" }, `${fixed(100 * c.success_rate, 0)}% on its maze`)),
    el("table", { class: "figures" },
      el("tr", {}, el("th", { text: "success, its maze" }), el("td", { text: fixed(c.success_rate) })),
      el("tr", {}, el("th", { text: "R̄, its maze" }), el("td", { text: signed(c.normalized_reward, 3) })),
      el("tr", {}, el("th", { text: "success, all the stage's mazes" }), el("td", { text: fixed(c.overall_success_rate) })),
      el("tr", {}, el("th", { text: "R̄, all the stage's mazes" }), el("td", { text: signed(c.overall_normalized_reward, 3) })),
      familyRows(c.family),
      el("tr", {}, el("th", { text: "env steps (lineage)" }), el("td", { text: `${count(c.env_steps)} (${count(c.lineage_steps)})` })),
      el("tr", {}, el("th", { text: "converged" }), el("td", { text: c.converged ? "yes" : "no" })),
      el("tr", {}, el("th", { text: "lineage" }), el("td", { text: c.lineage.join(" → ") }))),
    el("div", { class: "episodes" }, episodes),
    el("button", {
      class: "choose primary",
      onclick: (event) => choose(question, c.branch, event.target, `Choose branch ${c.branch}`),
    }, `Choose branch ${c.branch}`));
}

function episodeTile(stage, branch, result) {
  const own = result.index === branch;
  const rotations = result.success.map((ok, k) =>
    el("span", { class: ok ? "dot good" : "dot bad", title: `rotation ${k}: ${ok ? "reached" : "not reached"}, R̄ ${signed(result.normalized_reward[k])}, ${result.steps[k]} steps` }));
  const figure = el("figure", { class: own ? "episode own" : "episode" },
    el("div", { class: "animation loading", text: "playing…" }),
    el("figcaption", {},
      el("div", {}, own ? el("strong", { text: "its maze" }) : `branch ${result.index}'s maze`),
      el("div", { class: "rotations" }, rotations, ` R̄ ${signed(result.normalized_reward_mean)}`),
      el("div", { class: "muted episode-figures" })));
  fetch(`/api/episode/${stage}/${branch}/${result.index}`, { cache: "no-store" })
    .then((response) => response.json().then((data) => ({ ok: response.ok, data })))
    .then(({ ok, data }) => {
      const box = figure.querySelector(".animation");
      if (!ok) {
        box.textContent = data.error || "no animation";
        return;
      }
      box.replaceWith(el("img", { src: data.gif, alt: `branch ${branch} on maze ${result.index}`, class: "animation" }));
      figure.querySelector(".episode-figures").textContent =
        `${data.success ? "reached" : "not reached"} in ${data.steps} steps, ${data.collisions} collisions`;
    })
    .catch(() => { figure.querySelector(".animation").textContent = "no animation"; });
  return figure;
}

async function choose(question, branch, button, label) {
  const buttons = document.querySelectorAll("button.choose, #take-proposal");
  buttons.forEach((b) => (b.disabled = true));
  button.textContent = "Sending…";
  const { ok, status, data } = await post("/api/answer", { question: question.id, answer: branch });
  if (!ok) {
    document.getElementById("answer-error").textContent = data.error;
    buttons.forEach((b) => (b.disabled = false));
    button.textContent = label;
    if (status === 409) shownQuestion = null;
  }
}

// -- designing mazes --------------------------------------------------------------

function generateView(question) {
  editors.clear();
  const parent = question.parent;
  const forms = question.suggestions.map((maze, index) => mazeEditor(question, index, maze));
  const submit = el("button", { id: "submit-mazes", class: "primary", disabled: true,
    onclick: () => submitMazes(question) }, `Train on these ${question.k} mazes`);
  return el("div", {},
    el("h2", { text: `Stage ${question.stage}: design ${question.k} maze${question.k > 1 ? "s" : ""}` }),
    el("p", { class: "muted" },
      `Each maze trains one copy of the chosen agent (lineage ${question.lineage.join(" → ")}) in its 4 rotations. `,
      "Type a maze string or use the controls; nothing is sent until every maze is valid. ",
      el("span", { id: "waiting" })),
    el("div", { class: "references" },
      referenceCard("The agent's last maze", parent, null, lastResult(question.last_result)),
      referenceCard("The target", question.target, "Still to go from the last maze: ", null)),
    el("div", { class: "previous" }, el("span", { class: "muted", text: "The last stage's mazes: " }),
      question.previous.map((maze) => el("figure", { class: maze === parent.string ? "chosen" : "" },
        el("img", { class: "thumb", src: previewUrl(maze), alt: maze, title: maze }),
        el("figcaption", {}, el("code", { text: maze }))))),
    generateAdvice(question),
    el("div", { class: "editors" }, forms),
    el("div", { class: "actions" }, submit, el("span", { id: "answer-error", class: "error", role: "alert" })));
}

function lastResult(result) {
  // How the agent did on the maze it trained on last, and on the target's family.
  if (!result) return null;
  const reached = result.success.filter(Boolean).length;
  const dots = result.success.map((ok, k) =>
    el("span", { class: ok ? "dot good" : "dot bad", title: `rotation ${k}: ${ok ? "reached" : "not reached"}, R̄ ${signed(result.normalized_reward[k])}` }));
  const family = result.family;
  return el("div", { id: "last-result", class: "last-result" },
    el("div", {}, el("strong", { text: "Its result there: " }),
      `success ${fixed(result.success_rate)} (${reached} of ${result.success.length} rotations) `,
      el("span", { class: "rotations inline" }, dots),
      ` · R̄ ${signed(result.normalized_reward_mean, 3)}`),
    family ? el("div", { class: "muted" },
      `On the target's family (${family.mazes} mazes): success ${fixed(family.success_rate)}, R̄ ${signed(family.normalized_reward, 3)}`) : null);
}

function referenceCard(title, card, lead, extra) {
  return el("article", { class: "card reference" },
    el("h3", { text: title }),
    el("div", { class: "reference-body" },
      el("img", { class: "preview", src: previewUrl(card.string), alt: title }),
      el("div", {},
        el("code", { class: "maze-string", text: card.string }),
        extra,
        figuresList(card),
        lead && card.comparison ? el("p", { class: "muted", text: lead + card.comparison.changes.join(", ") }) : null)));
}

function figuresList(card) {
  return el("dl", { class: "maze-figures" },
    el("dt", { text: "class" }), el("dd", { text: card.class }),
    el("dt", { text: "path" }), el("dd", { text: `${card.path_length} cells` }),
    el("dt", { text: "intersections" }), el("dd", { text: card.intersections }),
    el("dt", { text: "signs" }), el("dd", { text: `${card.clues} clues, ${card.lures} lures, ${card.traps} traps` }),
    el("dt", { text: "Surprisingness" }), el("dd", { text: fixed(card.surprisingness, 3) }),
    el("dt", { text: "Deceptiveness" }), el("dd", { text: fixed(card.deceptiveness, 3) }),
    el("dt", { text: "difficulty" }), el("dd", { text: fixed(card.difficulty, 2) }));
}

// index -> {valid, string (the last valid, canonical), version (bumped by every edit), timer}
const editors = new Map();
//: How long typing pauses before the server is asked (the answer comes well within 0.5 s).
const DEBOUNCE_MS = 120;
//: The number fields: their names in messages, and whether they are whole numbers.
const NUMBER_FIELDS = {
  width: ["width", true], height: ["height", true], seed: ["seed", true],
  clue_value: ["clue lightness", false], lure_value: ["lure lightness", false], trap_value: ["trap lightness", false],
  p_lure: ["lure probability", false], p_trap: ["trap probability", false],
};

function mazeEditor(question, index, maze) {
  const id = (name) => `maze-${name}-${index}`;
  const number = (name, label, min, max, step) =>
    el("label", {}, label, el("input", { id: id(name), type: "number", min, max, step, "data-field": name }));
  const check = (name, label) => el("label", { class: "check" }, el("input", { id: id(name), type: "checkbox", "data-field": name }), label);
  const signRow = (kind, probability) =>
    el("div", { class: "sign-row" }, check(kind, `${kind}s`),
      number(`${kind}_value`, "lightness", 0.05, 1, 0.05),
      probability ? number(`p_${kind}`, "probability", 0.05, 1, 0.05) : null);
  const editor = el("article", { class: "card editor", id: id("editor"), "data-index": index },
    el("h3", {}, `Maze ${index + 1} `, el("span", { id: id("origin"), class: "pill origin" })),
    el("label", { class: "string" }, "maze string",
      el("input", { id: id("string"), class: "maze-input", type: "text", value: maze, spellcheck: "false", autocomplete: "off" })),
    el("p", { id: id("error"), class: "error inline", role: "alert" }),
    el("div", { class: "editor-body" },
      el("div", { class: "maze-view" },
        el("img", { id: id("preview"), class: "preview", alt: `preview of maze ${index + 1}` }),
        el("div", { id: id("figures") })),
      el("fieldset", { class: "controls" },
        el("legend", { text: "fields" }),
        el("div", { class: "row" }, number("width", "width", 2, 100, 1), number("height", "height", 2, 100, 1)),
        el("div", { class: "row" },
          el("label", {}, "start", el("select", { id: id("start"), "data-field": "start" },
            ["SW", "SE", "NE", "NW"].map((c) => el("option", { value: c, text: c })))),
          check("unicursive", "unicursive")),
        signRow("clue", false), signRow("lure", true), signRow("trap", true),
        el("div", { class: "row" },
          number("seed", "seed", 0, 2147483647, 1),
          el("button", { id: id("new-seed"), type: "button", onclick: () => { changed(question, index); update(question, index, { new_seed: true }); } }, "new seed")))));
  editors.set(index, { valid: false, string: maze, version: 0, timer: null });
  const input = editor.querySelector(".maze-input");
  // The string, typed: the fields follow it once the server has read it.
  input.addEventListener("input", () => {
    changed(question, index);
    later(question, index, () => ({}));
  });
  // Leaving the string: it shows its canonical form (never while it is being typed in).
  input.addEventListener("blur", () => {
    const entry = editors.get(index);
    if (entry.valid && entry.timer === null) input.value = entry.string;
  });
  // A field, typed or clicked: checked at once here, then the string follows it.
  editor.querySelectorAll("[data-field]").forEach((control) => {
    const onEdit = () => {
      changed(question, index);
      enableSigns(editor, readFields(editor));
      const problems = fieldProblems(editor);
      if (problems.length) {
        showProblems(index, problems.join("; "));
        return;
      }
      later(question, index, () => ({ fields: readFields(editor) }));
    };
    control.addEventListener(control.type === "number" ? "input" : "change", onEdit);
  });
  setTimeout(() => update(question, index, {}), 0);
  return editor;
}

function changed(question, index) {
  // Every edit makes answers to earlier requests stale: they never overwrite what was typed since.
  const entry = editors.get(index);
  entry.version += 1;
  entry.valid = false;
  clearTimeout(entry.timer);
  entry.timer = null;
  refreshSubmit(question);
}

function later(question, index, body) {
  const entry = editors.get(index);
  entry.timer = setTimeout(() => {
    entry.timer = null;
    update(question, index, body());
  }, DEBOUNCE_MS);
}

function fieldProblems(editor) {
  // Every bad number field, named: what the server would refuse, said before it is asked.
  const problems = [];
  editor.querySelectorAll('input[type="number"]').forEach((control) => {
    const [label, whole] = NUMBER_FIELDS[control.dataset.field] || [control.dataset.field, false];
    let problem = null;
    if (!control.disabled) {
      const value = Number(control.value);
      const min = Number(control.min);
      const max = Number(control.max);
      if (control.validity.badInput) problem = `${label} is not a number`;
      else if (control.value.trim() === "") problem = `${label} is empty`;
      else if (!Number.isFinite(value)) problem = `${label} ${control.value} is not a number`;
      else if (whole && !Number.isInteger(value)) problem = `${label} ${control.value} is not a whole number`;
      else if (whole && (value < min || value > max)) problem = `${label} ${control.value} is not in ${min}..${max}`;
      else if (!whole && (value <= 0 || value > 1)) problem = `${label} ${control.value} is not in (0, 1]`;
    }
    if (problem) {
      problems.push(problem);
      control.setAttribute("aria-invalid", "true");
    } else {
      control.removeAttribute("aria-invalid");
    }
  });
  return problems;
}

function showProblems(index, message) {
  const editor = document.getElementById(`maze-editor-${index}`);
  const errorBox = document.getElementById(`maze-error-${index}`);
  errorBox.textContent = message;
  errorBox.classList.remove("note");
  editor.classList.add("invalid");
}

function readFields(editor) {
  const fields = {};
  editor.querySelectorAll("[data-field]").forEach((control) => {
    const name = control.dataset.field;
    if (control.type === "checkbox") fields[name] = control.checked;
    else if (control.type === "number") fields[name] = control.value === "" ? null : Number(control.value);
    else fields[name] = control.value;
  });
  return fields;
}

function enableSigns(editor, fields) {
  for (const kind of ["clue", "lure", "trap"]) {
    editor.querySelectorAll(`[data-field$="_${kind}"], [data-field="${kind}_value"]`).forEach((c) => {
      c.disabled = !fields[kind];
    });
  }
}

function writeFields(editor, fields) {
  // The field with the focus is never written: the person is typing in it.
  editor.querySelectorAll("[data-field]").forEach((control) => {
    if (control === document.activeElement) return;
    const value = fields[control.dataset.field];
    if (control.type === "checkbox") control.checked = Boolean(value);
    else if (control.type !== "number" || Number(control.value) !== value || control.value === "") control.value = value;
    control.removeAttribute("aria-invalid");
  });
  enableSigns(editor, fields);
}

async function update(question, index, extra) {
  const editor = document.getElementById(`maze-editor-${index}`);
  if (!editor) return;
  const entry = editors.get(index);
  const version = entry.version;
  const input = document.getElementById(`maze-string-${index}`);
  const errorBox = document.getElementById(`maze-error-${index}`);
  // Fields change the last valid maze when the typed string is not one.
  const string = extra.fields && input.getAttribute("aria-invalid") === "true" ? entry.string : input.value;
  const body = { string, reference: question.parent.string, ...extra };
  const { ok, data } = await post("/api/maze", body);
  if (entry.version !== version || shownQuestion !== question.id) return; // edited since: stale
  if (!ok) {
    entry.valid = false;
    errorBox.textContent = data.error;
    errorBox.classList.remove("note");
    if (!extra.fields) input.setAttribute("aria-invalid", "true");
    editor.classList.add("invalid");
    refreshSubmit(question);
    return;
  }
  entry.valid = true;
  entry.string = data.string;
  if (input !== document.activeElement) input.value = data.string;
  input.removeAttribute("aria-invalid");
  editor.classList.remove("invalid");
  errorBox.textContent = data.notes.length ? `note: ${data.notes.join("; ")}` : "";
  errorBox.classList.toggle("note", data.notes.length > 0);
  writeFields(editor, data.fields);
  const origin = document.getElementById(`maze-origin-${index}`);
  const proposed = question.advice ? question.advice.mazes.indexOf(data.string) : -1;
  origin.textContent = proposed >= 0 ? `the advisor's maze ${proposed + 1}` : question.advice ? "yours" : "";
  origin.classList.toggle("advisor", proposed >= 0);
  document.getElementById(`maze-preview-${index}`).src = previewUrl(data.string);
  const comparison = data.comparison;
  document.getElementById(`maze-figures-${index}`).replaceChildren(
    figuresList(data),
    comparison ? el("p", { class: "comparison" },
      el("strong", { text: "vs the agent's last maze: " }), comparison.changes.join(", "),
      `; difficulty ${fixed(comparison.difficulty)} → ${fixed(data.difficulty)}`) : null);
  refreshSubmit(question);
}

function refreshSubmit(question) {
  const button = document.getElementById("submit-mazes");
  if (!button) return;
  const all = [...editors.values()];
  const ready = all.length === question.k && all.every((e) => e.valid);
  button.disabled = !ready;
  button.title = ready ? "" : "every maze must be valid first";
}

async function submitMazes(question) {
  const button = document.getElementById("submit-mazes");
  button.disabled = true;
  const mazes = [...Array(question.k).keys()].map((i) => editors.get(i).string);
  const { ok, status, data } = await post("/api/answer", { question: question.id, answer: mazes });
  if (ok) {
    button.textContent = "Sent: training starts…";
    return;
  }
  document.getElementById("answer-error").textContent = data.error;
  (data.details || []).forEach((problem, index) => {
    if (problem) document.getElementById(`maze-error-${index}`).textContent = problem;
  });
  if (status === 409) shownQuestion = null;
  else refreshSubmit(question);
}

// -- the end ------------------------------------------------------------------------

function finalView() {
  const final = state.final;
  const f = final.figures;
  return el("div", { id: "final" },
    el("h2", { text: "Session finished" }),
    el("p", { text: "The final agent on the standard evaluation suite (18 mazes × 4 rotations), then in the 4 rotations of the target:" }),
    el("table", { class: "figures final-figures" },
      el("tr", {}, el("th", { text: "success rate" }), el("td", { id: "final-success", text: fixed(f.success_rate, 3) })),
      el("tr", {}, el("th", { text: "normalized reward R̄" }), el("td", { text: fixed(f.normalized_reward, 3) })),
      el("tr", {}, el("th", { text: "input recognition" }), el("td", { text: fixed(f.input_recognition, 3) })),
      el("tr", {}, el("th", { text: "env steps" }), el("td", { text: count(f.env_steps) })),
      el("tr", {}, el("th", { text: "training seconds" }), el("td", { text: fixed(f.seconds, 1) })),
      el("tr", {}, el("th", { text: "final lineage" }), el("td", { text: (f.final_lineage || []).join(" → ") }))),
    el("p", { class: "muted", text: plainWords(final.headline) }),
    el("div", { class: "trajectories" }, final.files.filter((name) => name.startsWith("trajectories/"))
      .map((name) => el("figure", {},
        el("img", { src: `/files/${name}`, alt: name }),
        el("figcaption", { class: "muted", text: name.replace("trajectories/", "").replace(".png", "") })))),
    el("h3", { text: "Run folder" }),
    el("p", {}, el("code", { text: state.run.out })),
    el("ul", { class: "files" }, final.files.map((name) =>
      el("li", {}, el("a", { href: `/files/${name}`, target: "_blank", rel: "noopener" }, name)))));
}

function adviceTaken(d) {
  if (!d.advisor) return "–";
  if (d.kind === "select") return d.accepted ? "taken" : "overridden";
  return `kept ${d.accepted.filter(Boolean).length} of ${d.accepted.length}`;
}

function plainWords(text) {
  // The run's headline in the page's words: one name per quantity (R̄), no code names.
  return text.replaceAll("normalized_reward", "R̄").replaceAll("input_recognition", "input recognition");
}

function failedView() {
  return el("div", {},
    el("h2", { text: "The run stopped" }),
    el("p", { class: "error", id: "run-error", text: state.error }),
    el("p", { class: "muted", text: "The decisions made so far are kept: fix the cause and go on with amaze-curate --resume." }));
}

// -- history ----------------------------------------------------------------------

function drawHistory() {
  const history = state.history;
  const key = JSON.stringify([
    state.phase === "finished", history.decisions.length, history.stages.map((s) => s.selected),
  ]);
  if (key === shownHistory) return;
  shownHistory = key;
  const body = document.querySelector("#decisions tbody");
  body.replaceChildren(...history.decisions.map((d) => {
    const answer = d.kind === "select"
      ? `branch ${missing(d.choice) ? "–" : d.choice}${d.forced ? " (the only one)" : ""}`
      : d.mazes.join("  ");
    // A select decision is recorded before the next stage; the page names the stage it chose in.
    const stage = d.kind === "select" ? d.stage - 1 : d.stage;
    return el("tr", { "data-kind": d.kind, "data-stage": d.stage },
      el("td", { text: stage }),
      el("td", { text: d.kind === "select" ? "choose agent" : "design mazes" }),
      el("td", {}, d.kind === "select" ? answer : el("code", { text: answer })),
      el("td", { class: "advice-taken", text: adviceTaken(d) }),
      el("td", { text: d.time.replace("T", " ").replace("+00:00", "") }),
      el("td", { text: d.forced || d.stage === 0 ? "–" : duration(d.seconds) }));
  }));
  document.getElementById("no-decisions").hidden = history.decisions.length > 0;
  const figure = document.getElementById("curriculum-figure");
  figure.hidden = history.stages.length === 0;
  if (history.stages.length) {
    document.getElementById("curriculum-picture").src = `/api/curriculum.png?v=${encodeURIComponent(key)}`;
  }
}

poll();
