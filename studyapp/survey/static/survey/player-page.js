// Trial pages of a study played in the page: where the browser has WebGL 2, each clip's
// <motion-player> gets its payload and the card's <video> (the fallback) is removed
// before survey.js wires the cards; the players start together once every one has drawn
// its first frame (one clock, so each counts whole loops). Without WebGL 2 the players go
// and the videos play as in any study.
import { supported, playback } from "./player/motion-player.js";

const players = Array.from(document.querySelectorAll("[data-clip-card] motion-player[data-src]"));
if (supported()) {
  let waiting = players.length;
  for (const player of players) {
    player.closest("[data-clip-card]").querySelector("video").remove();
    player.addEventListener("loadeddata", () => {
      waiting -= 1;
      if (waiting === 0) playback.play();
    }, { once: true });
    player.setAttribute("src", player.dataset.src);
  }
} else {
  players.forEach((player) => player.remove());
}
