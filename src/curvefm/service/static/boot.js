// Shows why the page could not start when app.js or one of its imports (three.js) fails to load.
document.getElementById("app-script").addEventListener("error", async () => {
  let detail = "the page's scripts failed to load";
  try {
    const response = await fetch("/vendor/three/build/three.module.js");
    if (!response.ok) detail = (await response.json()).detail;
  } catch (error) {
    detail = `the service cannot be reached (${error.message})`;
  }
  const banner = document.getElementById("banner");
  banner.textContent = `The UI could not start: ${detail}.`;
  banner.hidden = false;
});
