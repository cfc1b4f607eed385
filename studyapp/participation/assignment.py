"""Balanced assignment of stimuli to trials and of sources to screen positions.

Called while the study row is locked (:meth:`StudyManager.lock`), so the counts read
here include every participant who started before and none who start concurrently.
Only main trials count: practice, catch and repeated trials are extras on top. Ties
are broken by the participant's seeded ``random.Random``, which makes a participant's
session reproducible from the database and their seed.

A session is then laid out by :func:`arrange`: catch trials at random places (never
first) and each repeated trial some trials after the one it repeats.
"""

from collections import Counter, defaultdict
from dataclasses import dataclass

from django.db.models import Count

from studyapp.participation.arena import retired
from studyapp.survey.models import Stimulus, Trial, TrialItem
from studyapp.survey.models.participation import Tally

# Trials at least between a trial and its repeat, when the session is long enough.
REPEAT_GAP = 2


def stimuli_by_action(study) -> dict[str, dict[str, list[Stimulus]]]:
    """Return ``{action: {source: [stimuli]}}`` of the stimuli of a study to be judged
    (an arena's retired sources left out)."""
    table = defaultdict(lambda: defaultdict(list))
    stimuli = (Stimulus.objects.judged().filter(study=study).exclude(source__in=retired(study))
               .order_by("action", "source", "pk"))
    for stimulus in stimuli:
        table[stimulus.action][stimulus.source].append(stimulus)
    return {action: dict(sources) for action, sources in table.items()}


def choose_balanced(by_source: dict[str, list], counts: Counter, rng, n: int) -> list:
    """Pick ``n`` stimuli: one per source where possible, the least-used first.

    Each source offers its least-used stimulus; when there are more sources than ``n``
    the sources whose offer is least used win; when there are fewer, the least-used
    remaining stimuli fill up. Returns fewer than ``n`` only if there are not enough.
    """

    def key(stimulus):
        return (counts[stimulus.pk], rng.random())

    offers = [min(stimuli, key=key) for _, stimuli in sorted(by_source.items()) if stimuli]
    chosen = sorted(offers, key=key)[:n]
    if len(chosen) < n:
        taken = {stimulus.pk for stimulus in chosen}
        rest = [s for _, stimuli in sorted(by_source.items()) for s in stimuli if s.pk not in taken]
        chosen += sorted(rest, key=key)[: n - len(chosen)]
    return chosen


def order_positions(stimuli: list, counts: Counter, rng) -> list:
    """Return ``stimuli`` in display order, counterbalancing sources over positions.

    Sources are seated in random order; each takes the free position where its source
    has been shown least often (ties at random), so over participants every source
    visits every position about equally often.
    """
    free = list(range(len(stimuli)))
    seats = [None] * len(stimuli)
    for stimulus in rng.sample(stimuli, len(stimuli)):
        position = min(free, key=lambda p: (counts[(stimulus.source, p)], rng.random()))
        free.remove(position)
        seats[position] = stimulus
    return seats


def assign(by_source: dict[str, list], items: Counter, positions: Counter, rng, n: int) -> list:
    """Choose and order one trial's stimuli, updating both counters in place."""
    seats = order_positions(choose_balanced(by_source, items, rng, n), positions, rng)
    for position, stimulus in enumerate(seats):
        items[stimulus.pk] += 1
        positions[(stimulus.source, position)] += 1
    return seats


@dataclass
class Pool:
    """What a new session is planned from, read once with the study row locked."""

    table: dict
    catches: list
    items: Counter
    positions: Counter
    practice: list
    shown: dict  # role -> {action: [stimuli]} (references, examples, anchors)

    @classmethod
    def of(cls, study, tally: Tally | None = None) -> "Pool":
        """Read the pool of ``study`` (its row locked); ``tally``: the counts already read
        by the start that plans this session (read here otherwise)."""
        others = Stimulus.objects.filter(study=study).exclude(role=Stimulus.Role.JUDGED)
        by_role = defaultdict(list)
        for stimulus in others.order_by("action", "pk"):
            by_role[stimulus.role].append(stimulus)
        shown = defaultdict(lambda: defaultdict(list))
        for role, stimuli in by_role.items():
            for stimulus in stimuli:
                shown[role][stimulus.action].append(stimulus)
        tally = tally or Tally.read(study)
        return cls(
            stimuli_by_action(study), by_role[Stimulus.Role.CATCH], tally.items, tally.positions,
            by_role[Stimulus.Role.PRACTICE], shown,
        )


def catch_counts(catches: list) -> Counter:
    """Return how many trial items each catch stimulus (by id) has had so far."""
    rows = (TrialItem.objects.filter(stimulus__in=[s.pk for s in catches])
            .values("stimulus").annotate(n=Count("pk")).values_list("stimulus", "n"))
    return Counter(dict(rows))


def pick_catch(catches: list, n: int, rng) -> list:
    """Return ``n`` catch stimuli in random order: the least used in the study so far
    (ties at random), each used once in the session before any twice.

    A study's catch clips are a family of broken versions (``stimulus_build``): handed
    out least used first, participants share one only once every one has been shown, so
    what one participant learns of a catch clip rarely helps another.
    """
    if not catches:
        return []
    used = catch_counts(catches)
    here: Counter = Counter()
    chosen = []
    for _ in range(n):
        stimulus = min(catches, key=lambda s: (here[s.pk], used[s.pk], rng.random()))
        here[stimulus.pk] += 1
        chosen.append(stimulus)
    rng.shuffle(chosen)
    return chosen


def arrange(main: list, catch: list, n_repeats: int, rng) -> list:
    """Return the session: main trials with catch trials and repeats placed among them.

    Catch trials go anywhere but first. Repeats show an early main trial again with its
    clips in mirrored order (left and right swapped in a pair), at least
    ``REPEAT_GAP`` trials later when the session allows it.
    """
    session = list(main)
    for plan in catch:
        session.insert(rng.randint(1, len(session)) if session else 0, plan)
    early = main[: max(n_repeats, (len(main) + 1) // 2)]
    for original in rng.sample(early, min(n_repeats, len(early))):
        at = session.index(original)
        later = min(at + 1 + REPEAT_GAP, len(session))
        session.insert(rng.randint(later, len(session)), original.repeated())
    return session
