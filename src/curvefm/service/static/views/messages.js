// Messages to the user: toasts, errors, the connection banner, and progress rows for jobs.

const TOAST_MS = { info: 4000, error: 12000 };

/** A short message in the corner; errors stay longer and can be closed. */
export function toast(text, kind = "info") {
  const element = document.createElement("div");
  element.className = `toast ${kind}`;
  element.setAttribute("role", kind === "error" ? "alert" : "status");
  const close = Object.assign(document.createElement("button"), { type: "button", textContent: "✕", title: "close" });
  close.addEventListener("click", () => element.remove());
  element.append(text, close);
  document.getElementById("toasts").append(element);
  setTimeout(() => element.remove(), TOAST_MS[kind]);
}

/** An error as a toast (and in the console): "context: message". */
export function report(error, context) {
  console.error(context, error);
  toast(`${context}: ${error.message}`, "error");
}

/** The banner under the top bar (text), or none (null). */
export function banner(text) {
  const element = document.getElementById("banner");
  element.hidden = text === null;
  element.textContent = text ?? "";
}

/** One job's progress: a label, a bar and the job's message. */
export class ProgressRow {
  constructor(container, label) {
    this.element = document.createElement("div");
    this.element.className = "progress-row";
    this.label = Object.assign(document.createElement("span"), { className: "progress-label", textContent: label });
    this.bar = Object.assign(document.createElement("progress"), { max: 1, value: 0 });
    this.message = Object.assign(document.createElement("span"), { className: "progress-message" });
    this.element.append(this.label, this.bar, this.message);
    container.append(this.element);
  }

  update(job) {
    this.bar.value = job.progress;
    this.message.textContent = `${job.state} ${Math.round(100 * job.progress)}% ${job.message}`;
  }

  finish(text, ok = true) {
    this.bar.value = ok ? 1 : this.bar.value;
    this.element.classList.add(ok ? "ok" : "failed");
    this.message.textContent = text;
  }
}
