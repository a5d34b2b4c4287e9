"use strict";
// Placeholder until the page (service.md 12) lands: shows /api/status.
fetch("/api/status").then(r => r.json()).then(s => {
  document.getElementById("status").textContent = JSON.stringify(s, null, 2);
});
