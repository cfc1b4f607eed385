// Keyboard shortcuts for answers given with radio buttons: a key names one choice
// (data-key on its input: "r", "g", "1".."5", "arrowleft", "arrowright"). Keys typed
// into a text field are left alone, and so are the arrow keys inside a radio group.
(function () {
  "use strict";

  var form = document.querySelector("[data-trial-form]");
  if (!form) { return; }

  document.addEventListener("keydown", function (event) {
    if (event.altKey || event.ctrlKey || event.metaKey) { return; }
    var key = event.key.toLowerCase();
    var target = event.target;
    if (target && target.matches) {
      if (target.matches("select, textarea, input:not([type=radio])")) { return; }
      if (target.matches("input[type=radio]") && key.indexOf("arrow") === 0) { return; }
    }
    var match = Array.prototype.filter.call(form.querySelectorAll("input[data-key]"), function (input) {
      return input.dataset.key === key;
    });
    if (match.length !== 1) { return; }
    event.preventDefault();
    match[0].checked = true;
    match[0].dispatchEvent(new Event("change", { bubbles: true }));
  });
})();
