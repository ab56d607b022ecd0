// Entry point of the page (index.html loads it as a module): starts the client, or says why it
// cannot run here.

import { App } from "./app.js";

try {
  const app = new App(document, window);
  window.marzipan = app;
  app.start();
} catch (e) {
  const p = document.createElement("p");
  p.className = "error";
  p.setAttribute("role", "alert");
  p.textContent = `Marzipan cannot start in this browser: ${e.message}`;
  document.body.prepend(p);
}
