// Who is logged in (in the top bar) and, once the service refused the page's login, how to log in.
import { state } from "../store.js";
import { $ } from "./dom.js";

export function showLogin() {
  const { user, loggedOut } = state;
  $("user-box").hidden = user === null;
  $("user-name").textContent = user ? `${user.name}${user.admin ? " (admin)" : ""}` : "";
  $("login-needed").hidden = !loggedOut;
}
