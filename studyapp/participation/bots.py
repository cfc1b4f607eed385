"""Simulated participants: bots that take a study through its real HTTP pages.

As oTree's bots do, each bot opens the participant link with its own cookie jar and walks
the one page sequence (:data:`studyapp.participation.flow.PAGE_SEQUENCE`): on each page it asks
that page how a bot fills it in (``Page.bot_fill``), which asks back the bot's policy. On
a trial page the bot fetches every clip the page shows, whole, as a browser does, waits
at least as long as the clips play (the server refuses answers sooner), reports each clip
played once, and answers through the study type (``StudyType.bot_answer``). Pages never
say where a clip comes from; a policy that needs the source gets it from the database by
the clip's token (the command runs beside the database), never from the page. On an
instructed check the bot gives the answer asked for (``StudyType.obey``; the instruction
is read from the database too, as a person reads it on the page), except the
inattentive one.

Policies (``POLICIES``):

- ``random``: every answer uniformly at random.
- ``prefer-real``: real clips best, broken (catch) clips worst, the rest at random.
- ``bt``: Bradley-Terry strengths ``s`` per source (``--strengths real=4,a2m=3``;
  unnamed sources 1, catch clips ``CATCH_STRENGTH``). Ranking: Plackett-Luce sampling,
  each next place drawn with probability proportional to ``s``. Pairwise: left wins
  with probability ``s_l / (s_l + s_r)``. Fake or real: "real" with probability
  ``logistic(log s - c)``, ``c`` the mean log strength of the study's sources. Rating:
  ``round(3 + 1.5 (log s - c) + e)``, ``e ~ N(0, 0.6)``, clipped to 1..5.
  Best of K and MUSHRA read each clip's utility (log strength, centred, plus a Gumbel
  draw): the clip of highest utility is picked; a slider is set to ``50 + 25 (u - 1)``.
  With ``--clip-sd SD`` clips vary about their source: a clip's log strength is its
  source's plus a fixed normal draw of standard deviation ``SD`` (:func:`clip_effect`, from
  the clip's stimulus id and ``--clip-seed``), in every answer above; catch clips do not
  vary. Without it (the default) every clip of a source is alike.
- ``inattentive``: at random, except that every catch trial is answered wrongly (the
  broken clip treated as the best) and every instructed check with another answer than
  the one asked for: the participant ends with the failed-attention outcome.
- ``decline``: does not consent (the no-consent outcome); ``screen-out``: consents but
  fails the study's screening questions (the screened-out outcome).
"""

from __future__ import annotations

import hashlib
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

from motion.registry import Registry
from studyapp.participation.forms import AGE_RANGES, GENDERS
from studyapp.survey.models import Stimulus, Trial, TrialItem

CATCH = "catch"  # the pseudo-source bots see for a catch clip
# The User-Agent every bot sends: the server stores it (Participant.user_agent), so the
# export, the report and the dashboard mark bots' participants and answers as simulated
# (is_simulated). Bots of earlier versions sent urllib's own agent, which no browser does.
USER_AGENT = "motion-study-bot/1 (simulated participant)"
BOT_AGENTS = (USER_AGENT, "Python-urllib/")


def is_simulated(user_agent) -> bool:
    """Return whether a participant with this stored User-Agent was a bot."""
    return (user_agent or "").startswith(BOT_AGENTS)


CATCH_STRENGTH = 0.05
MAX_STEPS = 500
TIMEOUT = 30
WAIT_MARGIN_S = 0.15  # beyond the clips' length, as the page's own playback would take


class SimulationError(RuntimeError):
    """A bot could not go on (an unexpected page, a refused answer, no server)."""


# Reading pages


class FormReader(HTMLParser):
    """Collect a page's forms, its clips, its completion code and where it sends people."""

    def __init__(self):
        super().__init__()
        self.forms: list[dict] = []
        self.clips: list[tuple[str, bool]] = []  # (video URL, required)
        self.code_open = False
        self.code = ""
        self.exit_url = ""
        self.heading = ""
        self.in_h1 = False
        self._required = False
        self._select = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "form":
            self.forms.append({"trial": "data-trial-form" in attrs, "fields": [], "radios": {},
                               "selects": {}})
        elif tag == "figure" and "data-clip-card" in attrs:
            self._required = "data-required" in attrs
        elif tag == "video" and attrs.get("src"):
            self.clips.append((attrs["src"], self._required))
        elif tag == "select" and self.forms and attrs.get("name"):
            self.forms[-1]["selects"][attrs["name"]] = []
            self._select = attrs["name"]
        elif tag == "option" and self.forms and self._select:
            self.forms[-1]["selects"][self._select].append(attrs.get("value", ""))
        elif tag in ("input", "textarea") and self.forms and attrs.get("name"):
            kind = attrs.get("type", tag)
            if kind == "radio":
                self.forms[-1]["radios"].setdefault(attrs["name"], []).append(attrs.get("value"))
            elif kind not in ("checkbox", "submit", "button"):
                self.forms[-1]["fields"].append((attrs["name"], attrs.get("value") or ""))
        elif tag == "output" and "data-completion-code" in attrs:
            self.code_open = True
        elif tag == "a" and "data-exit-url" in attrs:
            self.exit_url = attrs.get("href", "")
        elif tag == "h1":
            self.in_h1 = True

    def handle_endtag(self, tag):
        if tag == "output":
            self.code_open = False
        elif tag == "h1":
            self.in_h1 = False
        elif tag == "select":
            self._select = None

    def handle_data(self, data):
        if self.code_open:
            self.code += data.strip()
        if self.in_h1:
            self.heading += data.strip()


@dataclass
class TrialPage:
    """What a bot reads off a trial page, plus the sources it looked up."""

    fields: dict
    tokens: list  # judged clips in screen order (position 0 first; in a pair, left first)
    choices: list  # values of a trial-level choice (pairwise)
    radios: dict = field(default_factory=dict)
    sources: dict = field(default_factory=dict)

    @classmethod
    def read(cls, form: dict, judged: list) -> "TrialPage":
        return cls(dict(form["fields"]), judged, form["radios"].get("choice", []),
                   form["radios"])


class ClipSource(str):
    """A clip's source name that also carries the clip (``stimulus``: its stimulus id).

    Study types pass it to the policy as the source's name (it compares, hashes and
    prints as that name); a policy that lets clips of one source differ reads
    ``stimulus``."""

    stimulus: int | None = None

    def __new__(cls, source: str, stimulus: int | None = None):
        made = super().__new__(cls, source)
        made.stimulus = stimulus
        return made


def item_info(tokens) -> dict[str, tuple]:
    """Return ``{item token: (source, role, duration)}`` from the database, the source a
    :class:`ClipSource` naming the clip; catch clips read as ``CATCH``."""
    rows = TrialItem.objects.filter(token__in=tokens).values_list(
        "token", "role", "stimulus__source", "stimulus__role", "stimulus__duration", "stimulus_id")
    return {token: (CATCH if stimulus_role == Stimulus.Role.CATCH else ClipSource(source, stimulus),
                    role, duration)
            for token, role, source, stimulus_role, duration, stimulus in rows}


def clip_effect(stimulus: int, sd: float, seed: int = 0) -> float:
    """Return clip ``stimulus``'s fixed deviation from its source's log strength: a normal
    draw of standard deviation ``sd``, the same for every bot of every run with ``seed``."""
    return sd * random.Random(f"clip-{seed}-{stimulus}").gauss(0.0, 1.0)


def instruction_of(tokens) -> dict:
    """Return the instruction of the trial showing the items ``tokens`` ({} for a trial
    that is no instructed check)."""
    trial = Trial.objects.filter(items__token__in=tokens, kind=Trial.Kind.INSTRUCTED).first()
    return trial.instruction if trial is not None else {}


def contrary(study, instruction: dict, n_judged: int, rng) -> dict:
    """Return another instruction of the study's type about the same clip (or about a
    clip at all, when that is all it names): an answer to it never passes
    ``instruction`` (``StudyType.instruct``)."""
    for _ in range(1000):
        other = study.kind.instruct(study, n_judged, rng)
        same_clip = other.get("position") == instruction.get("position")
        if other != instruction and (same_clip or set(instruction) == {"position"}):
            return other
    raise SimulationError(f"no other instruction than {instruction} to disobey")


# Policies


class Policy:
    """How a bot answers; study types ask for these decisions."""

    consents = True
    passes_screening = True
    follows_instructions = True

    def __init__(self, rng: random.Random, strengths: dict | None = None, sources=()):
        self.rng = rng

    def utility(self, source: str) -> float:
        """Return how good a clip of ``source`` looks to this bot now (a latent score)."""
        return self.rng.gauss(0.0, 1.0)

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

    def utility(self, source):
        return self.score(source) + self.rng.random() * 0.5

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


class Inattentive(Policy):
    """At random, but a broken clip always looks best and instructions go unread: every
    catch trial and instructed check is failed."""

    follows_instructions = False

    def utility(self, source):
        return 10.0 if source == CATCH else self.rng.gauss(0.0, 1.0)

    def order(self, sources):
        keys = {i: (s != CATCH, self.rng.random()) for i, s in enumerate(sources)}
        return sorted(keys, key=keys.get)

    def rating(self, source):
        return 5 if source == CATCH else self.rng.randint(1, 5)

    def is_real(self, source):
        return True if source == CATCH else self.rng.random() < 0.5

    def prefer(self, left, right, ties):
        if CATCH in (left, right):
            return "left" if left == CATCH else "right"
        return self.rng.choice(["left", "right", *ties])


class Decline(Policy):
    consents = False


class ScreenOut(Policy):
    passes_screening = False


class BradleyTerry(Policy):
    """Strengths per source; with ``clip_sd`` each clip's log strength is its source's plus
    :func:`clip_effect` (read from a :class:`ClipSource`; a plain name varies not)."""

    def __init__(self, rng, strengths=None, sources=(), clip_sd: float = 0.0, clip_seed: int = 0):
        super().__init__(rng)
        self.strengths = {CATCH: CATCH_STRENGTH, **(strengths or {})}
        self.clip_sd, self.clip_seed = clip_sd, clip_seed
        logs = [math.log(self.strength(s)) for s in sources] or [0.0]
        self.centre = sum(logs) / len(logs)

    def strength(self, source):
        base = self.strengths.get(source, 1.0)
        stimulus = getattr(source, "stimulus", None)
        if self.clip_sd and stimulus is not None:
            return base * math.exp(clip_effect(stimulus, self.clip_sd, self.clip_seed))
        return base

    def utility(self, source):
        """Log strength, centred, plus a Gumbel draw (a Plackett-Luce/BT choice)."""
        gumbel = -math.log(-math.log(self.rng.random() or 1e-12) or 1e-12)
        return math.log(self.strength(source)) - self.centre + gumbel

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


POLICIES = Registry("bot policy")
for _name, _policy in [("random", Policy), ("prefer-real", PreferReal), ("bt", BradleyTerry),
                       ("inattentive", Inattentive), ("decline", Decline),
                       ("screen-out", ScreenOut)]:
    POLICIES.add(_name, _policy)


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
    exit_url: str = ""
    trials: int = 0
    refused: list = field(default_factory=list)


class Bot:
    """One simulated participant with its own cookies.

    ``watch=False`` makes a bot that answers without fetching the clips or waiting: the
    server refuses it (:class:`SimulationError`), which is what it is for.
    """

    def __init__(self, study, policy: Policy, rng: random.Random, pace: float = 1.0,
                 watch: bool = True):
        self.study = study
        self.policy = policy
        self.rng = rng
        self.pace = pace
        self.watch = watch
        self.base = ""
        self.reader = None
        self.opener = urllib.request.build_opener(
            urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar())
        )
        self.opener.addheaders = [("User-Agent", USER_AGENT)]

    def fetch(self, url: str, data: dict | None = None) -> tuple[str, str]:
        """Return ``(final url, html)`` of a GET, or of a POST when ``data`` is given."""
        body = urllib.parse.urlencode(data).encode() if data is not None else None
        try:
            with self.opener.open(url, body, timeout=TIMEOUT) as response:
                return response.geturl(), response.read().decode()
        except urllib.error.HTTPError as error:
            text = error.read().decode(errors="replace")
            problems = re.findall(r"<li>(.*?)</li>", text, re.S)
            raise SimulationError(f"{url}: HTTP {error.code} {'; '.join(problems)}") from None
        except urllib.error.URLError as error:
            raise SimulationError(f"{url}: {error.reason}") from None
        except OSError as error:  # a timeout or a dropped connection: this bot stops
            raise SimulationError(f"{url}: {type(error).__name__}: {error}") from None

    def fetch_clip(self, url: str) -> int:
        """GET a clip whole, as a browser's media player does; return its size."""
        try:
            with self.opener.open(urllib.parse.urljoin(self.base, url), timeout=TIMEOUT) as r:
                return len(r.read())
        except (urllib.error.URLError, OSError) as error:
            raise SimulationError(f"{url}: {getattr(error, 'reason', error)}") from None

    def run(self, entry_url: str) -> Outcome:
        """Take the study from its entry link to its last page."""
        from studyapp.participation.flow import PAGES

        outcome = Outcome()
        self.base = entry_url
        url, html = self.fetch(entry_url)
        for _ in range(MAX_STEPS):
            self.reader = reader = FormReader()
            reader.feed(html)
            name = urllib.parse.urlparse(url).path.rstrip("/").rsplit("/", 1)[-1]
            if name == "done":
                outcome.completion_code, outcome.exit_url = reader.code, reader.exit_url
                return outcome
            page = PAGES.get(name)
            form = next((f for f in reader.forms if name != "trial" or f["trial"]), None)
            if page is None or form is None:
                raise SimulationError(f"stopped at {url}: {reader.heading or 'no form'}")
            data = page.bot_fill(dict(form["fields"]), form, self)
            outcome.trials += name == "trial"
            url, html = self.fetch(url, data)
        raise SimulationError(f"no end after {MAX_STEPS} pages")

    # What the pages ask (Page.bot_fill)

    def consent(self, form) -> dict:
        if not self.policy.consents:
            return {"decline": "1"}
        data = {"agree": "1"}
        for i, question in enumerate(self.study.platform.screening):
            answers = question["answers"]
            if self.policy.passes_screening:
                data[f"screen_{i}"] = question["accept"][0]
            else:
                data[f"screen_{i}"] = next((a for a in answers if a not in question["accept"]),
                                           answers[0])
        return data

    def answer_trial(self, fields: dict, form: dict) -> dict:
        tokens = [name.removeprefix("plays_") for name in fields if name.startswith("plays_")]
        info = item_info(tokens)
        judged = [t for t in tokens if info.get(t, ("", "", 0))[1] == TrialItem.Role.JUDGED]
        if self.watch:
            for url, required in self.reader.clips:
                if required:
                    self.fetch_clip(url)
            longest = max((d for _, role, d in info.values()), default=0.0)
            time.sleep(longest * max(self.pace, 1.0) + WAIT_MARGIN_S)
        page = TrialPage.read(form, judged)
        page.sources = {token: info[token][0] for token in judged}
        answer = self.study.kind.bot_answer(page, self.policy)
        instruction = instruction_of(tokens)
        if instruction:
            answer = self.follow(page, instruction, answer)
        answer = self.every_criterion(answer)
        plays = {f"plays_{t}": "1" for t in tokens}
        return plays | answer

    def follow(self, page, instruction: dict, answer: dict) -> dict:
        """Give the answer an instructed check asks for, or, for a policy that does not
        read instructions, one asked for by another instruction about the same clip
        (which never passes; see ``StudyType.instruct``)."""
        kind = self.study.kind
        if not self.policy.follows_instructions:
            instruction = contrary(self.study, instruction, len(page.tokens), self.rng)
        return kind.obey(page, instruction, answer)

    def every_criterion(self, answer: dict) -> dict:
        """Answer the study's other criteria as the first (names prefixed ``key.``)."""
        criteria = self.study.kind.criteria(self.study)
        out = dict(answer)
        for criterion in criteria[1:]:
            out.update({f"{criterion.key}.{name}": value for name, value in answer.items()})
        return out

    def about_me(self) -> dict:
        return {
            "age_range": self.rng.choice(AGE_RANGES + [""]),
            "gender": self.rng.choice([value for value, _ in GENDERS] + [""]),
            "comments": "",
        }


def person_id(run, i: int) -> str:
    """Return a bot's platform id: 24 hex digits (a valid Prolific id), from run and number."""
    return hashlib.sha1(f"sim-{run}-{i}".encode()).hexdigest()[:24]


def entry_url(study, url: str, person: str) -> str:
    """Return the participant link of ``study`` on server ``url``, for crowd id ``person``
    (the parameters its platform's links carry: ``Platform.entry_params``)."""
    parts = urllib.parse.urlsplit(url)
    path = parts.path if "/s/" in parts.path else study.get_absolute_url()
    query = urllib.parse.parse_qsl(parts.query) + study.platform.entry_params(study, person)
    return urllib.parse.urlunsplit(
        (parts.scheme, parts.netloc, path, urllib.parse.urlencode(query), "")
    )
