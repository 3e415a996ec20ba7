// Who else has the open session open: their names in the top bar, after the session's title.
import { state } from "../store.js";

/** The names of the other users who have the open session open (state.viewers, less the page's own user). */
export function showViewers() {
  const element = viewersElement();
  const others = state.viewers.filter((name) => name !== state.user?.name);
  element.hidden = others.length === 0;
  element.textContent = others.length ? `also open by ${others.join(", ")}` : "";
  element.title = others.length ? "users with this session open now: their changes show here as they make them" : "";
}

function viewersElement() {
  let element = document.getElementById("viewers");
  if (!element) {
    element = Object.assign(document.createElement("span"), { id: "viewers", className: "viewers", hidden: true });
    element.setAttribute("aria-live", "polite");
    document.getElementById("session-title").after(element);
  }
  return element;
}
