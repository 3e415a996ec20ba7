// Logging in and out. The login URL that `curvefm serve` prints carries ?token=: the page trades it for the
// service's login cookie (HttpOnly, so no script can read it) and takes it out of the address bar and history.
// Where the lab's single sign-on is configured, the login banner offers it (/auth/oidc/login, which comes back
// with the cookie set). A logged-in user may make a new token for scripts.
import { api } from "../api.js";
import { loggedIn, loggedOut, state, subscribe } from "../store.js";
import { hideNewToken, showLogin, showNewToken, showSingleSignOn } from "../views/login.js";
import { report, toast } from "../views/messages.js";

/** Follow the login (state.user, state.loggedOut), which requests change. */
export function watchLogin() {
  subscribe("login", showLogin);
  subscribe("login", () => state.loggedOut && offerSingleSignOn());
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

async function offerSingleSignOn() {
  try {
    showSingleSignOn((await api.loginMethods()).single_sign_on);
  } catch (error) {
    report(error, "Asking how to sign in failed");
  }
}

/** Make a new token for scripts, after the user agreed that the old one stops working, and show it once. */
export async function makeToken() {
  const question =
    "Make a new token for scripts? Your token so far stops working, and your logins in other browsers end.";
  if (!window.confirm(question)) return;
  try {
    showNewToken((await api.newToken()).token);
  } catch (error) {
    report(error, "Making a token failed");
  }
}

export async function logOut() {
  try {
    await api.logout();
    hideNewToken();
    loggedOut();
    toast("Logged out.");
  } catch (error) {
    report(error, "Logging out failed");
  }
}
