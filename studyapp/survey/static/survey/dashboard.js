// The admin's live study dashboard: fetch its sections every few seconds and put in
// those that changed. The clip list keeps its previews (a playing clip is not
// interrupted) and only has its counts updated, unless the clips themselves changed.
(function () {
  "use strict";

  function start() {
    var root = document.getElementById("dashboard");
    if (!root) return;
    var url = root.dataset.url;
    var every = Math.max(1000, +root.dataset.refreshMs || 10000);
    var stamp = document.getElementById("dashboard-updated");
    var sections = document.getElementById("dashboard-sections");
    var last = {};
    sections.querySelectorAll("[data-section]").forEach(function (s) {
      last[s.dataset.section] = s.outerHTML;
    });
    var busy = false;

    function clipIds(node) {
      return Array.prototype.map.call(node.querySelectorAll("[data-clip]"),
        function (row) { return row.dataset.clip; }).join(",");
    }

    function put(fresh) {
      fresh.querySelectorAll("[data-section]").forEach(function (section) {
        var name = section.dataset.section;
        var html = section.outerHTML;
        if (last[name] === html) return;
        var old = sections.querySelector('[data-section="' + name + '"]');
        if (!old) { sections.appendChild(section); last[name] = html; return; }
        if (name === "clips" && clipIds(old) === clipIds(section) &&
            !!old.querySelector("[data-clip-bots]") === !!section.querySelector("[data-clip-bots]")) {
          section.querySelectorAll("[data-clip-judgements], [data-clip-bots]").forEach(function (cell) {
            var key = cell.hasAttribute("data-clip-bots") ? "data-clip-bots" : "data-clip-judgements";
            var target = old.querySelector("[" + key + '="' + cell.getAttribute(key) + '"]');
            if (target) target.textContent = cell.textContent;
          });
        } else {
          old.replaceWith(section);
        }
        last[name] = html;
      });
    }

    function refresh() {
      if (busy || document.hidden) return;
      busy = true;
      fetch(url, {credentials: "same-origin", headers: {"Accept": "application/json"}})
        .then(function (response) {
          if (!response.ok) throw new Error("HTTP " + response.status);
          return response.json();
        })
        .then(function (body) {
          var holder = document.createElement("template");
          holder.innerHTML = body.html;
          put(holder.content);
          root.dataset.generatedAt = body.data.generated_at;
          if (stamp) stamp.textContent = "updated " + new Date().toLocaleTimeString();
        })
        .catch(function (error) {
          if (stamp) stamp.textContent = "not updated: " + error.message;
        })
        .finally(function () { busy = false; });
    }

    setInterval(refresh, every);
    document.addEventListener("visibilitychange", function () { if (!document.hidden) refresh(); });
  }

  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
  else start();
})();
