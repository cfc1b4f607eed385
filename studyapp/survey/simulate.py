"""Simulated participants: bots that take a study through its real HTTP pages.

As oTree's bots do, each bot opens the participant link with its own cookie jar,
consents, reads the instructions, answers every trial through the page's own form
(reporting each clip played once, as the play gate requires), answers the closing
questions and reads its completion code. Pages never say where a clip comes from; a
policy that needs the source gets it from the database by the clip's token (the
command runs beside the database), never from the page. Before answering, a bot waits
``pace`` times its longest clip, as a person must, so its answer times survive the
analysis' too-fast rule (``pace=0`` answers at once).

Policies (``POLICIES``):

- ``random``: every answer uniformly at random.
- ``prefer-real``: real clips best, broken (catch) clips worst, the rest at random.
- ``bt``: Bradley-Terry strengths ``s`` per source (``--strengths real=4,a2m=3``;
  unnamed sources 1, catch clips ``CATCH_STRENGTH``). Ranking: Plackett-Luce sampling,
  each next place drawn with probability proportional to ``s``. Pairwise: left wins
  with probability ``s_l / (s_l + s_r)``. Fake or real: "real" with probability
  ``logistic(log s - c)``, ``c`` the mean log strength of the study's sources. Rating:
  ``round(3 + 1.5 (log s - c) + e)``, ``e ~ N(0, 0.6)``, clipped to 1..5.
"""

from __future__ import annotations

import http.cookiejar
import math
import random
import re
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass, field
from html.parser import HTMLParser

from studyapp.survey.forms import AGE_RANGES, GENDERS
from studyapp.survey.models import Stimulus

CATCH = "catch"  # the pseudo-source bots see for a catch clip
CATCH_STRENGTH = 0.05
MAX_STEPS = 500
TIMEOUT = 30


class SimulationError(RuntimeError):
    """A bot could not go on (an unexpected page, a refused answer, no server)."""


# Reading pages


class FormReader(HTMLParser):
    """Collect the fields of a page's forms and its completion code."""

    def __init__(self):
        super().__init__()
        self.forms: list[dict] = []
        self.code_open = False
        self.code = ""
        self.heading = ""
        self.in_h1 = False

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "form":
            self.forms.append({"trial": "data-trial-form" in attrs, "fields": [], "radios": {}})
        elif tag in ("input", "select", "textarea") and self.forms and attrs.get("name"):
            kind = attrs.get("type", tag)
            if kind == "radio":
                self.forms[-1]["radios"].setdefault(attrs["name"], []).append(attrs.get("value"))
            elif kind not in ("checkbox", "submit", "button"):
                self.forms[-1]["fields"].append((attrs["name"], attrs.get("value") or ""))
        elif tag == "output" and "data-completion-code" in attrs:
            self.code_open = True
        elif tag == "h1":
            self.in_h1 = True

    def handle_endtag(self, tag):
        if tag == "output":
            self.code_open = False
        elif tag == "h1":
            self.in_h1 = False

    def handle_data(self, data):
        if self.code_open:
            self.code += data.strip()
        if self.in_h1:
            self.heading += data.strip()


@dataclass
class TrialPage:
    """What a bot reads off a trial page, plus the sources it looked up."""

    fields: dict
    tokens: list  # clips in screen order (position 0 first; in a pair, left first)
    choices: list  # values of a trial-level choice (pairwise)
    sources: dict = field(default_factory=dict)

    @classmethod
    def read(cls, form: dict) -> "TrialPage":
        fields = dict(form["fields"])
        names = [name for name, _ in form["fields"]]
        tokens = [name.removeprefix("plays_") for name in names if name.startswith("plays_")]
        return cls(fields, tokens, form["radios"].get("choice", []))


def sources_of(tokens) -> dict[str, str]:
    """Return ``{token: source}`` from the database; catch clips read as ``CATCH``."""
    rows = Stimulus.objects.filter(token__in=tokens).values_list("token", "source", "is_catch")
    return {token: CATCH if is_catch else source for token, source, is_catch in rows}


def longest_clip(tokens) -> float:
    """Return the duration in seconds of the longest of these clips."""
    durations = Stimulus.objects.filter(token__in=tokens).values_list("duration", flat=True)
    return max(durations, default=0.0)


# Policies


class Policy:
    """How a bot answers; each study type asks for one of these four decisions."""

    def __init__(self, rng: random.Random, strengths: dict | None = None, sources=()):
        self.rng = rng

    def order(self, sources: list[str]) -> list[int]:
        """Return the indices of ``sources`` from best to worst."""
        return self.rng.sample(range(len(sources)), len(sources))

    def rating(self, source: str) -> int:
        return self.rng.randint(1, 5)

    def is_real(self, source: str) -> bool:
        return self.rng.random() < 0.5

    def prefer(self, left: str, right: str, ties: list[str]) -> str:
        return self.rng.choice(["left", "right", *ties])


class PreferReal(Policy):
    def score(self, source):
        return {"real": 2, CATCH: 0}.get(source, 1)

    def order(self, sources):
        keys = {i: (-self.score(s), self.rng.random()) for i, s in enumerate(sources)}
        return sorted(keys, key=keys.get)

    def rating(self, source):
        return {"real": self.rng.randint(4, 5), CATCH: 1}.get(source, self.rng.randint(1, 3))

    def is_real(self, source):
        return source == "real"

    def prefer(self, left, right, ties):
        if self.score(left) == self.score(right):
            return self.rng.choice(["left", "right"])
        return "left" if self.score(left) > self.score(right) else "right"


class BradleyTerry(Policy):
    def __init__(self, rng, strengths=None, sources=()):
        super().__init__(rng)
        self.strengths = {CATCH: CATCH_STRENGTH, **(strengths or {})}
        logs = [math.log(self.strength(s)) for s in sources] or [0.0]
        self.centre = sum(logs) / len(logs)

    def strength(self, source):
        return self.strengths.get(source, 1.0)

    def order(self, sources):
        left = list(range(len(sources)))
        out = []
        while left:
            weights = [self.strength(sources[i]) for i in left]
            pick = self.rng.choices(left, weights)[0]
            out.append(pick)
            left.remove(pick)
        return out

    def rating(self, source):
        score = 3 + 1.5 * (math.log(self.strength(source)) - self.centre) + self.rng.gauss(0, 0.6)
        return min(5, max(1, round(score)))

    def is_real(self, source):
        logit = math.log(self.strength(source)) - self.centre
        return self.rng.random() < 1 / (1 + math.exp(-logit))

    def prefer(self, left, right, ties):
        s_left, s_right = self.strength(left), self.strength(right)
        return "left" if self.rng.random() < s_left / (s_left + s_right) else "right"


POLICIES = {"random": Policy, "prefer-real": PreferReal, "bt": BradleyTerry}


def parse_strengths(text: str) -> dict[str, float]:
    """Read ``"real=4,a2m=3"`` as ``{"real": 4.0, "a2m": 3.0}``; raise ValueError."""
    strengths = {}
    for part in filter(None, (p.strip() for p in (text or "").split(","))):
        name, _, value = part.partition("=")
        try:
            strengths[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"strength {part!r} is not NAME=NUMBER") from None
        if not strengths[name.strip()] > 0:
            raise ValueError(f"strength {part!r} must be positive")
    return strengths


# The bot


@dataclass
class Outcome:
    completion_code: str = ""
    trials: int = 0


class Bot:
    """One simulated participant with its own cookies."""

    def __init__(self, study, policy: Policy, rng: random.Random, pace: float = 1.0):
        self.study = study
        self.policy = policy
        self.rng = rng
        self.pace = pace
        self.opener = urllib.request.build_opener(
            urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar())
        )

    def fetch(self, url: str, data: dict | None = None) -> tuple[str, str]:
        """Return ``(final url, html)`` of a GET, or of a POST when ``data`` is given."""
        body = urllib.parse.urlencode(data).encode() if data is not None else None
        try:
            with self.opener.open(url, body, timeout=TIMEOUT) as response:
                return response.geturl(), response.read().decode()
        except urllib.error.HTTPError as error:
            text = error.read().decode(errors="replace")
            problems = re.findall(r"<li>(.*?)</li>", text)
            raise SimulationError(f"{url}: HTTP {error.code} {'; '.join(problems)}") from None
        except urllib.error.URLError as error:
            raise SimulationError(f"{url}: {error.reason}") from None

    def run(self, entry_url: str) -> Outcome:
        """Take the study from its entry link to the completion page."""
        outcome = Outcome()
        url, html = self.fetch(entry_url)
        for _ in range(MAX_STEPS):
            reader = FormReader()
            reader.feed(html)
            name = urllib.parse.urlparse(url).path.rstrip("/").rsplit("/", 1)[-1]
            if name == "done":
                outcome.completion_code = reader.code
                return outcome
            form = next((f for f in reader.forms if name != "trial" or f["trial"]), None)
            if form is None or name not in ("consent", "instructions", "trial", "about-you"):
                raise SimulationError(f"stopped at {url}: {reader.heading or 'no form'}")
            data = dict(form["fields"])
            if name == "consent":
                data["agree"] = "1"
            elif name == "trial":
                data.update(self.answer(TrialPage.read(form)))
                outcome.trials += 1
            elif name == "about-you":
                data.update(self.about_me())
            url, html = self.fetch(url, data)
        raise SimulationError(f"no end after {MAX_STEPS} pages")

    def answer(self, page: TrialPage) -> dict:
        if self.pace > 0:
            time.sleep(self.pace * longest_clip(page.tokens))
        page.sources = sources_of(page.tokens)
        answer = self.study.kind.simulate_answer(page, self.policy)
        plays = {name: "1" for name in page.fields if "plays" in name.split("_")}
        return plays | answer

    def about_me(self) -> dict:
        return {
            "age_range": self.rng.choice(AGE_RANGES + [""]),
            "gender": self.rng.choice([value for value, _ in GENDERS] + [""]),
            "comments": "",
        }


def entry_url(study, url: str, person: str) -> str:
    """Return the participant link of ``study`` on server ``url``, for crowd id ``person``."""
    parts = urllib.parse.urlsplit(url)
    path = parts.path if "/s/" in parts.path else study.get_absolute_url()
    query = urllib.parse.parse_qsl(parts.query) + [("PROLIFIC_PID", person)]
    return urllib.parse.urlunsplit(
        (parts.scheme, parts.netloc, path, urllib.parse.urlencode(query), "")
    )
