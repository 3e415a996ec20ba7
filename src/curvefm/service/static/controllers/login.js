// Logging in and out. The login URL that `curvefm serve` prints carries ?token=: the page trades it for the
// service's login cookie (HttpOnly, so no script can read it) and takes it out of the address bar and history.
import { api } from "../api.js";
import { loggedIn, loggedOut, subscribe } from "../store.js";
import { showLogin } from "../views/login.js";
import { report, toast } from "../views/messages.js";

/** Follow the login (state.user, state.loggedOut), which requests change. */
export function watchLogin() {
  subscribe("login", showLogin);
}

/** Log in with the URL's token, else find out whether a cookie from before still logs in; resolves to whether
 * the page is logged in. */
export async function logIn() {
  const url = new URL(window.location.href);
  const token = url.searchParams.get("token");
  if (token !== null) {
    url.searchParams.delete("token");
    window.history.replaceState(null, "", url);
  }
  try {
    loggedIn(token !== null ? await api.login(token) : await api.me());
    return true;
  } catch (error) {
    if (error.status !== 401) report(error, "Logging in failed");
    return false;
  }
}

export async function logOut() {
  try {
    await api.logout();
    loggedOut();
    toast("Logged out.");
  } catch (error) {
    report(error, "Logging out failed");
  }
}
