// Shared by every study type: play clips on repeat, count complete plays, log what the
// page saw (play, pause, seek, ended, page hidden/visible, window blur/focus) into the
// answer, keep the answer button shut until each clip has played through once and every
// question of the form is answered, copy the completion code. The server checks again
// on its own (clips fetched to their end, their playing time passed): this gate is the
// participant's guide, not the judge.
(function () {
  "use strict";

  var MAX_EVENTS = 400;
  var MAX_DETAIL = 200; // characters of a fallback's message (answers.MAX_DETAIL_CHARS)

  function eventLog(form) {
    var field = form.querySelector("[data-events]");
    var events = [];
    var dropped = false;
    function log(name, position, detail) {
      if (!field) { return; }
      if (events.length >= MAX_EVENTS) {
        if (!dropped) { events.push([Math.round(performance.now()), "truncated", null]); }
        dropped = true;
      } else {
        var event = [Math.round(performance.now()), name, position === undefined ? null : position];
        if (detail !== undefined) { event.push(String(detail).slice(0, MAX_DETAIL)); }
        events.push(event);
      }
      field.value = JSON.stringify(events);
    }
    document.addEventListener("visibilitychange", function () {
      log(document.hidden ? "hidden" : "visible");
    });
    window.addEventListener("blur", function () { log("blur"); });
    window.addEventListener("focus", function () { log("focus"); });
    return log;
  }

  function setupTrial(form) {
    // The answer's response is the next trial page (one request per answer): make this
    // history entry a plain visit of the page, so a reload or the back button asks the
    // server for the current trial instead of posting the last answer again.
    if (window.history && window.history.replaceState) {
      window.history.replaceState(null, "", window.location.href);
    }
    var log = eventLog(form);
    var cards = Array.prototype.slice.call(form.querySelectorAll("[data-clip-card]"));
    var gated = cards.filter(function (card) { return card.hasAttribute("data-required"); });
    // The first time an action's scoring-standard examples are shown, they play first and
    // the clips to judge start once each example has played through: never eight videos
    // at once on a phone.
    var leads = cards.filter(function (card) {
      return card.dataset.role === "example" && card.hasAttribute("data-required");
    });
    var waiting = leads.length ? cards.filter(function (card) { return leads.indexOf(card) < 0; }) : [];
    var submit = form.querySelector("[data-submit]");
    var gate = form.querySelector("[data-gate]");
    var label = submit.textContent;

    function playsOf(card) {
      return Number(card.querySelector("[data-plays]").value) || 0;
    }

    function update() {
      var watched = gated.filter(function (card) { return playsOf(card) > 0; }).length;
      var allWatched = watched === gated.length;
      var answered = form.checkValidity();
      var ready = allWatched && answered;
      submit.disabled = !ready;
      form.classList.toggle("is-ready", ready);
      if (!allWatched) {
        gate.textContent = "Watched to the end: " + watched + " of " + gated.length +
          ". The button unlocks once every clip has played through.";
      } else if (!answered) {
        gate.textContent = "All clips watched. Answer for every clip to continue.";
      } else {
        gate.textContent = "All clips watched. Submit when your answer is ready.";
      }
    }

    function start(card, video) {
      var playing = video.play();
      if (playing && playing.catch) {
        playing.then(function () {
          card.querySelector("[data-play]").hidden = true;
        }).catch(function () {
          // Autoplay refused (e.g. a phone's data saver): ask for a tap instead.
          card.querySelector("[data-play]").hidden = false;
        });
      }
    }

    function watchPlayer(card, player) {
      // The in-page player (player-page.js): it loops on the page's one clock and fires
      // one "ended" per whole loop, so a play is counted exactly as for a video.
      var plays = card.querySelector("[data-plays]");
      var state = card.querySelector("[data-state]");
      var position = Number(card.getAttribute("data-position"));
      // Once the trial fell back to its videos (player-page.js), a removed player's
      // events are no longer the page's.
      function live(handler) {
        return function (event) { if (player.isConnected) { handler(event); } };
      }
      ["play", "pause", "seek"].forEach(function (name) {
        player.addEventListener(name, live(function () { log(name, position); }));
      });
      player.addEventListener("loadeddata", live(function () { state.textContent = "Playing…"; }));
      player.addEventListener("ended", live(function () {
        log("ended", position);
        plays.value = String(playsOf(card) + 1);
        card.classList.add("is-watched");
        state.textContent = "Watched";
        update();
      }));
      player.addEventListener("error", live(function () {
        log("error", position);
        state.textContent = "Could not load: please reload the page";
      }));
    }

    function watchVideo(card, video) {
      var plays = card.querySelector("[data-plays]");
      var state = card.querySelector("[data-state]");
      var position = Number(card.getAttribute("data-position"));
      var lazy = card.hasAttribute("data-lazy");
      // Loop by hand: with the loop attribute a video never fires "ended", which is
      // exactly the event that proves it was played through.
      video.loop = false;
      ["play", "pause", "seeked", "waiting"].forEach(function (name) {
        video.addEventListener(name, function () {
          log(name === "seeked" ? "seek" : name, position);
        });
      });
      video.addEventListener("ended", function () {
        log("ended", position);
        plays.value = String(playsOf(card) + 1);
        if (waiting.length && leads.every(function (lead) { return playsOf(lead) > 0; })) {
          var now = waiting;
          waiting = [];
          now.forEach(function (other) { start(other, other.querySelector("video")); });
        }
        card.classList.add("is-watched");
        state.textContent = "Watched";
        update();
        video.currentTime = 0;
        start(card, video);
      });
      video.addEventListener("playing", function () {
        if (!playsOf(card)) { state.textContent = "Playing…"; }
      });
      video.addEventListener("error", function () {
        log("error", position);
        state.textContent = "Could not load: please reload the page";
      });
      video.addEventListener("click", function () {
        if (video.paused) { start(card, video); } else { video.pause(); }
      });
      card.querySelector("[data-play]").addEventListener("click", function () {
        start(card, video);
      });
      if (lazy) {
        // Folded examples: nothing plays until the participant opens them.
        state.textContent = "Tap to play";
        card.querySelector("[data-play]").hidden = false;
      } else if (waiting.indexOf(card) >= 0) {
        state.textContent = "Plays after the examples";
      } else {
        start(card, video);
      }
    }

    cards.forEach(function (card) {
      var video = card.querySelector("video");
      var player = card.querySelector("motion-player[src]");
      if (player) {
        watchPlayer(card, player);
      } else if (video) {
        watchVideo(card, video);
      }
    });

    // The trial went back to its videos (player-page.js: a payload failed to load or
    // read, or WebGL was lost): log why, and count plays from the videos only, from
    // nothing, so every clip of the trial is watched in the one medium.
    form.addEventListener("player-fallback", function (event) {
      var detail = event.detail || {};
      log("fallback", typeof detail.position === "number" ? detail.position : null,
          detail.message || "");
      waiting = leads.length ? cards.filter(function (card) { return leads.indexOf(card) < 0; }) : [];
      cards.forEach(function (card) {
        card.querySelector("[data-plays]").value = "0";
        card.classList.remove("is-watched");
      });
      cards.forEach(function (card) {
        var video = card.querySelector("video");
        if (video) { watchVideo(card, video); }
      });
      update();
    });

    form.addEventListener("submit", function (event) {
      if (submit.disabled) { event.preventDefault(); return; }
      // One click, one answer: the server ignores repeats, but people need feedback.
      window.setTimeout(function () {
        submit.disabled = true;
        submit.textContent = "Saving…";
      }, 0);
    });
    form.addEventListener("change", update);
    window.addEventListener("pageshow", function () {
      submit.textContent = label;
      update();
    });
    update();
    // Once every deferred script (this and the study type's) has run, say so.
    document.addEventListener("DOMContentLoaded", function () {
      form.setAttribute("data-ready", "");
    });
  }

  function setupCopy(button) {
    var target = document.getElementById(button.getAttribute("data-copy"));
    button.addEventListener("click", function () {
      var text = target.textContent.trim();
      var done = function () { button.textContent = "Copied"; };
      if (navigator.clipboard && window.isSecureContext) {
        navigator.clipboard.writeText(text).then(done);
      } else {
        var range = document.createRange();
        range.selectNodeContents(target);
        var selection = window.getSelection();
        selection.removeAllRanges();
        selection.addRange(range);
        document.execCommand("copy");
        done();
      }
    });
  }

  document.querySelectorAll("[data-trial-form]").forEach(setupTrial);
  document.querySelectorAll("[data-copy]").forEach(setupCopy);
})();
