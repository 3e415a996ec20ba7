// Who is logged in (in the top bar) and, once the service refused the page's login, how to log in.
import { state } from "../store.js";
import { $ } from "./dom.js";

export function showLogin() {
  const { user, loggedOut } = state;
  $("user-box").hidden = user === null;
  $("user-name").textContent = user ? `${user.name}${user.admin ? " (admin)" : ""}` : "";
  $("login-needed").hidden = !loggedOut;
}

/** The login banner's single sign-on button: ``sso`` is { label, login_url }, or null where none is configured. */
export function showSingleSignOn(sso) {
  $("sso-login").hidden = sso === null;
  if (sso === null) return;
  $("sso-label").textContent = sso.label;
  $("sso-login").href = sso.login_url;
}

/** A new token, shown until the user is done with it (it cannot be shown again). */
export function showNewToken(token) {
  $("new-token").textContent = token;
  $("token-box").hidden = false;
}

export function hideNewToken() {
  $("new-token").textContent = "";
  $("token-box").hidden = true;
}
