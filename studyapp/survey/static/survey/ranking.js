// The ranking lists of a preference-ranking trial (one per question). A list's order
// is the answer: row k has rank k. Rows move by drag and drop (mouse: HTML5 drag and
// drop; touch and pen: pointer events on the grip), by the arrow buttons, or by each
// row's rank menu, and every move rewrites the menus, the numbers and the badges on the
// clips. A list starts unranked: the order shown becomes the answer only once the
// participant moves a row or presses "Keep this order", so an untouched page cannot be
// submitted.
(function () {
  "use strict";

  document.querySelectorAll("[data-ranking-panel]").forEach(setupPanel);

  function setupPanel(panel) {
  var list = panel.querySelector("[data-ranking]");
  var announcer = panel.querySelector("[data-announce]");
  var keep = panel.querySelector("[data-keep-order]");
  var badges = list.dataset.question === "0";
  var ranked = false;
  var dragged = null;
  var byPointer = false; // true while a finger or pen (not HTML5 drag) moves a row

  function rows() {
    return Array.prototype.slice.call(list.querySelectorAll(".rank-row"));
  }

  function nameOf(row) {
    return row.querySelector(".rank-name").textContent;
  }

  function renumber() {
    var all = rows();
    all.forEach(function (row, index) {
      var rank = String(index + 1);
      row.querySelector(".rank-num").textContent = ranked ? rank : "–";
      row.querySelector(".rank-select").value = ranked ? rank : "";
      row.querySelector("[data-move='-1']").disabled = index === 0;
      row.querySelector("[data-move='1']").disabled = index === all.length - 1;
      var card = document.querySelector("[data-clip-card][data-clip='" + row.dataset.clip + "']");
      if (card && badges) { card.querySelector("[data-badge]").textContent = ranked ? "Rank " + rank : ""; }
    });
    if (keep) { keep.hidden = ranked; }
    list.dispatchEvent(new Event("change", { bubbles: true }));
  }

  function markRanked() {
    ranked = true;
  }

  function announce(row) {
    if (announcer) {
      announcer.textContent = nameOf(row) + " is now rank " + (rows().indexOf(row) + 1) + ".";
    }
  }

  function moveTo(row, index) {
    markRanked();
    var others = rows().filter(function (other) { return other !== row; });
    index = Math.max(0, Math.min(index, others.length));
    list.insertBefore(row, others[index] || null);
    renumber();
    announce(row);
  }

  // Put the dragged row where the pointer is: before the first row whose middle lies
  // below it, so moving across half a row is enough to swap.
  function placeAt(y) {
    var others = rows().filter(function (row) { return row !== dragged; });
    var before = null;
    for (var i = 0; i < others.length; i += 1) {
      var box = others[i].getBoundingClientRect();
      if (y < box.top + box.height / 2) { before = others[i]; break; }
    }
    if (dragged.nextElementSibling !== before) {
      markRanked();
      list.insertBefore(dragged, before);
      renumber();
    }
  }

  function startDrag(row, pointer) {
    dragged = row;
    byPointer = pointer;
    row.classList.add("is-dragging");
    list.classList.add("is-sorting");
  }

  function endDrag() {
    if (!dragged) { return; }
    var row = dragged;
    row.classList.remove("is-dragging");
    list.classList.remove("is-sorting");
    dragged = null;
    byPointer = false;
    renumber();
    announce(row);
  }

  if (keep) {
    keep.addEventListener("click", function () {
      markRanked();
      renumber();
      if (announcer) { announcer.textContent = "The order shown is your ranking."; }
    });
  }

  list.addEventListener("change", function (event) {
    if (!event.target.classList || !event.target.classList.contains("rank-select")) { return; }
    if (event.target.value === "") { renumber(); return; }
    var row = event.target.closest(".rank-row");
    moveTo(row, Number(event.target.value) - 1);
    event.target.focus();
  });

  list.addEventListener("click", function (event) {
    var button = event.target.closest("[data-move]");
    if (!button) { return; }
    var row = button.closest(".rank-row");
    moveTo(row, rows().indexOf(row) + Number(button.dataset.move));
    // Keep focus on a usable button so arrow presses can continue.
    var next = button.disabled ? row.querySelector("[data-move]:not([disabled])") : button;
    next.focus();
  });

  list.addEventListener("dragstart", function (event) {
    var row = event.target.closest && event.target.closest(".rank-row");
    if (!row) { return; }
    event.dataTransfer.effectAllowed = "move";
    event.dataTransfer.setData("text/plain", nameOf(row));
    startDrag(row, false);
  });
  list.addEventListener("dragover", function (event) {
    if (!dragged) { return; }
    event.preventDefault();
    event.dataTransfer.dropEffect = "move";
    placeAt(event.clientY);
  });
  list.addEventListener("drop", function (event) {
    if (dragged) { event.preventDefault(); }
  });
  list.addEventListener("dragend", endDrag);

  // Touch and pen: HTML5 drag and drop is unreliable there, so the grip follows the
  // finger with pointer events (the grip has touch-action: none, so no scrolling).
  list.addEventListener("pointerdown", function (event) {
    var grip = event.target.closest(".grip");
    if (!grip || event.pointerType === "mouse") { return; }
    event.preventDefault();
    grip.setPointerCapture(event.pointerId);
    startDrag(grip.closest(".rank-row"), true);
  });
  list.addEventListener("pointermove", function (event) {
    if (byPointer) { placeAt(event.clientY); }
  });
  // A native drag cancels the pointer that began it; only pointer drags end here.
  ["pointerup", "pointercancel"].forEach(function (type) {
    list.addEventListener(type, function () {
      if (byPointer) { endDrag(); }
    });
  });

  renumber();
  }
})();
