// Trial pages of a study played in the page: where the browser has WebGL 2, each clip's
// <motion-player> gets its payload and the card's <video> (the fallback) is taken out
// before survey.js wires the cards; the players start together once every one has drawn
// its first frame (one clock, so each counts whole loops). Without WebGL 2 the players go
// and the videos play as in any study.
//
// If any player of the trial fires `error` (its payload could not be fetched or read, or
// the WebGL context was lost), the whole trial goes back to its videos: every player is
// removed, every video put back where it was, and the trial form gets a `player-fallback`
// event (detail: `message`, `position` of the clip that failed, null for a lost context) on which
// survey.js starts counting plays from the videos afresh and logs `fallback`. All clips
// of a trial use one medium, so the page keeps one way of counting.
import { supported, playback } from "./player/motion-player.js";

const players = Array.from(document.querySelectorAll("[data-clip-card] motion-player[data-src]"));
const MAX_MESSAGE = 200;

function fallBack(message, position) {
  const cards = players.map((player) => player.closest("[data-clip-card]"));
  const forms = new Set(cards.map((card) => card.closest("form")).filter(Boolean));
  playback.pause("api");
  players.forEach((player, k) => {
    const video = kept[k];
    if (video && !video.isConnected) player.replaceWith(video);
    else player.remove();
  });
  const detail = { message: String(message || "").slice(0, MAX_MESSAGE), position };
  forms.forEach((form) => form.dispatchEvent(new CustomEvent("player-fallback", { detail })));
}

const kept = [];
if (supported()) {
  let waiting = players.length;
  let fallen = false;
  const fail = (player, event) => {
    if (fallen) return;
    fallen = true;
    const detail = event.detail || {};
    const message = detail.message || "the player failed";
    const card = player.closest("[data-clip-card]");
    // A lost context is the page's, not one clip's.
    const position = card && !detail.contextLost ? Number(card.getAttribute("data-position")) : null;
    // survey.js wires the cards before DOMContentLoaded: fall back once it has.
    if (document.readyState === "loading") {
      document.addEventListener("DOMContentLoaded", () => fallBack(message, position), { once: true });
    } else {
      fallBack(message, position);
    }
  };
  for (const player of players) {
    const video = player.closest("[data-clip-card]").querySelector("video");
    kept.push(video);
    if (video) video.remove();
    player.addEventListener("loadeddata", () => {
      waiting -= 1;
      if (waiting === 0 && !fallen) playback.play();
    }, { once: true });
    player.addEventListener("error", (event) => fail(player, event));
    player.setAttribute("src", player.dataset.src);
  }
} else {
  players.forEach((player) => player.remove());
}
