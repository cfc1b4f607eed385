"""Participants, their trials and the items a trial shows, with their answers.

A trial shows items: the clips to judge (``TrialItem.role`` ``judged``) and the clips
shown beside them for context (a real ``reference``, the ``example`` clips of a scoring
standard). Every item has its own opaque token, so the same clip shown twice (a repeated
trial) is two URLs, and the server knows which item's bytes a participant fetched.

A judgement is one judged item of an answered trial that is not a practice trial. Its
answer is stored per criterion: ``TrialItem.answers`` (``{"preference": 2}``, a rank) and
``Trial.answers`` (``{"preference": "left"}``, a pairwise choice). What a trial asks, how
its answer is checked, graded, exported and analysed belongs to the study's type
(:mod:`studyapp.survey.study_types`); nothing here branches on it.
"""

import random
import secrets
from collections import Counter
from dataclasses import dataclass

from django.db import connection, models, transaction
from django.db.models import Count, Exists, F, Max, OuterRef, Q
from django.urls import reverse
from django.utils import timezone

from studyapp.stimuli.media import merge_ranges
from studyapp.survey.models.rows import Columns, Statements, Values, cursor, prepared, quote, read
from studyapp.survey.models.stimuli import Stimulus
from studyapp.survey.models.study import Study, Unavailable, new_token


class ParticipantManager(models.Manager):
    def find(self, study: Study, key: str):
        """Return the participant whose platform id is ``key``, or None (the entry link
        and the consent ask: one statement written out, :mod:`.rows`)."""
        if not key:
            return None
        found = read(_FIND.get(), [study.pk, key], PARTICIPANT_ROW)
        return found[0][0] if found else None

    def holding_a_place(self, study: Study):
        """Return the participants who count against ``max_participants``: finished, or
        consented, still within the study's time limit and not idle."""
        people = self.filter(study=study, consented_at__isnull=False)
        finished = Q(completed_at__isnull=False)
        return people.filter(finished | self._active(study, timezone.now()))

    @staticmethod
    def _active(study: Study, now) -> Q:
        """Return who is taking part now: consented, unfinished, within the time limit and
        the idle limit (the last answer, or consent, recent enough)."""
        active = Q(completed_at__isnull=True, outcome="", consented_at__isnull=False)
        limit, idle = study.time_limit(), study.idle_limit()
        if limit is not None:
            active &= Q(consented_at__gt=now - limit)
        if idle is not None:
            active &= Q(active_at__gt=now - idle) | Q(active_at__isnull=True,
                                                      consented_at__gt=now - idle)
        return active

    def release_places(self, study: Study) -> int:
        """Give the ``timed_out`` outcome to everyone taking part past the time limit or
        the idle limit (their later requests get the timed-out page); return how many.
        Called with the study row locked, before places are counted: no daemon needed."""
        lost = self.filter(study=study, completed_at__isnull=True, outcome="",
                           consented_at__isnull=False).exclude(self._active(study, timezone.now()))
        return lost.update(outcome=Participant.Outcome.TIMED_OUT)

    def enroll(self, study: Study, external_ids: dict, key: str, user_agent: str = "",
               outcome: str = "") -> "Participant":
        """Admit a consenting participant (or record one who declined or was screened out
        with ``outcome``), or raise :class:`Unavailable`."""
        with transaction.atomic():
            study = Study.objects.lock(study.pk)
            existing = self.find(study, key)
            if existing is not None:
                if existing.is_finished():
                    raise Unavailable("taken")
                if existing.timed_out():
                    raise Unavailable("timed_out")
                return existing
            if study.status != Study.Status.OPEN:
                raise Unavailable("closed")
            if self.sharing_ids(study, external_ids, key):
                raise Unavailable("session_taken")
            if not outcome and study.max_participants is not None:
                self.release_places(study)
                if study.is_full():
                    raise Unavailable("full")
            now = timezone.now()
            participant = self.create(
                study=study,
                external_ids=external_ids,
                external_key=key,
                seed=secrets.randbits(62),
                consented_at=None if outcome else now,
                active_at=None if outcome else now,
                completed_at=now if outcome else None,
                outcome=outcome,
                completion_code=study.platform.code_for(outcome) if outcome else "",
                user_agent=user_agent[:300],
            )
            participant.n_trials = 0  # none yet: the next page need not ask
            return participant

    def sharing_ids(self, study: Study, external_ids: dict, key: str) -> bool:
        """Whether another participant of ``study`` came with one of the ids that must be
        unique (a Prolific ``SESSION_ID`` with ``strict_ids``)."""
        unique = study.platform.unique_ids(external_ids)
        if not unique:
            return False
        same = Q()
        for name, value in unique.items():
            same |= Q(**{f"external_ids__{name}": value})
        return self.filter(study=study).filter(same).exclude(external_key=key).exists()

    def start(self, participant: "Participant") -> int:
        """Create the participant's trials once, balanced against everyone before them;
        return how many trials the participant has."""
        with transaction.atomic():
            study = Study.objects.lock(participant.study_id)
            if participant.trials.exists():
                return participant.trials.count()  # started already (a second submit)
            tally = Tally.read(study)
            plans = study.kind.plan_trials(study, random.Random(participant.seed), tally)
            # At most three INSERTs (on PostgreSQL) whatever the number of trials, as the
            # study's row is locked: the trials, the repeats (they point at their
            # originals), every item; then the balance counts (an upsert and the row of
            # what is counted).
            created = {}
            for repeats in (False, True):
                planned = [(index, plan) for index, plan in enumerate(plans)
                           if (plan.repeat_of is not None) == repeats]
                trials = Trial.objects.bulk_create(
                    Trial(participant=participant, index=index, action=plan.action,
                          prompt=plan.prompt, kind=plan.kind,
                          repeat_of=created.get(id(plan.repeat_of)),
                          instruction=plan.instruction)
                    for index, plan in planned
                )
                created.update((id(plan), trial) for (_, plan), trial in zip(planned, trials))
            items = TrialItem.objects.bulk_create(
                [item for plan in plans for item in plan.items(created[id(plan)])])
            tally.store(list(created.values()), items)
        return len(plans)

    def by_token(self, study: Study, token: str):
        """Return the study's participant with ``token``, or None, with ``n_trials``,
        ``n_practice`` and ``current_id`` (the first unanswered trial, None before the
        start and after the last answer). Every page asks this, so it is one SQL
        statement written out (building it as an annotated queryset costs more CPU than
        running it)."""
        rows = read(_BY_TOKEN.get(), [study.pk, token], PARTICIPANT_ROW, Values(4))
        if not rows:
            return None
        participant, (study_version, n_trials, n_practice, current_id) = rows[0]
        participant.study_version, participant.n_trials = study_version, n_trials
        participant.n_practice, participant.current_id = n_practice, current_id
        return participant

    def record_demographics(self, participant: "Participant", answers: dict) -> None:
        """Store the answers to the closing questions once; later posts change nothing."""
        self.filter(pk=participant.pk, demographics__isnull=True).update(demographics=answers)
        participant.refresh_from_db(fields=["demographics"])

    def mark_timed_out(self, participant: "Participant") -> None:
        """Record that the participant ran out of time or sat idle too long (as the
        platform times them out); the place is free again, and no code is given."""
        if self.filter(pk=participant.pk, outcome="", completed_at=None).update(
            outcome=Participant.Outcome.TIMED_OUT
        ):
            participant.outcome = Participant.Outcome.TIMED_OUT

    def finish(self, participant: "Participant", now) -> None:
        """Decide the outcome after the last answer (the study's catch rule) and set the
        completion code: the platform's code of that outcome, or a random code."""
        study = participant.study
        failed = Trial.objects.filter(
            participant=participant, kind__in=Trial.CHECK_KINDS, catch_passed=False
        ).count()
        outcome = (
            Participant.Outcome.FAILED_ATTENTION
            if failed > study.max_failed_catch
            else Participant.Outcome.COMPLETED
        )
        code = study.platform.code_for(outcome)
        if self.filter(pk=participant.pk, completed_at__isnull=True).update(
            completed_at=now, completion_code=code, outcome=outcome
        ):
            participant.completed_at, participant.completion_code = now, code
            participant.outcome = outcome

    def with_checks(self):
        """Annotate judgements, the attention checks (catch and instructed trials, as
        ``n_catch``, ``failed_catch``) and the repeated trials, answered and failed."""
        answered = Q(trials__answered_at__isnull=False)
        failed = Q(trials__catch_passed=False)

        def trials(kind, also):
            kinds = Q(trials__kind__in=kind) if isinstance(kind, tuple) else Q(trials__kind=kind)
            return Count("trials", filter=also & kinds, distinct=True)

        return self.annotate(
            n_judgements=Count(
                "trials__items",
                filter=answered
                & ~Q(trials__kind=Trial.Kind.PRACTICE)
                & Q(trials__items__role=TrialItem.Role.JUDGED),
            ),
            n_catch=trials(Trial.CHECK_KINDS, answered),
            failed_catch=trials(Trial.CHECK_KINDS, failed),
            n_repeat=trials(Trial.Kind.REPEAT, answered),
            inconsistent_repeats=trials(Trial.Kind.REPEAT, failed),
        )


class Participant(models.Model):
    class Outcome(models.TextChoices):
        COMPLETED = "completed", "Completed"
        FAILED_ATTENTION = "failed_attention", "Failed the attention checks"
        NO_CONSENT = "no_consent", "Did not consent"
        SCREENED_OUT = "screened_out", "Screened out"
        TIMED_OUT = "timed_out", "Ran out of time"

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="participants")
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    external_ids = models.JSONField(default=dict, blank=True, help_text="Crowd-platform ids.")
    external_key = models.CharField(
        max_length=200, blank=True, help_text="The platform id that names this person."
    )
    seed = models.BigIntegerField(help_text="Seed of this participant's random order.")
    created_at = models.DateTimeField(auto_now_add=True)
    consented_at = models.DateTimeField(null=True, blank=True)
    active_at = models.DateTimeField(
        null=True, blank=True, help_text="Consent or the last answer: idle since then."
    )
    completed_at = models.DateTimeField(null=True, blank=True)
    outcome = models.CharField(
        max_length=20, choices=Outcome.choices, blank=True, help_text="Blank while taking part."
    )
    completion_code = models.CharField(max_length=64, blank=True)
    user_agent = models.CharField(max_length=300, blank=True)
    demographics = models.JSONField(
        null=True, blank=True, help_text="Age range, gender, comments; empty until asked."
    )

    objects = ParticipantManager()

    class Meta:
        ordering = ["study", "created_at"]
        constraints = [
            models.UniqueConstraint(
                fields=["study", "external_key"],
                condition=~Q(external_key=""),
                name="one_participation_per_person",
            )
        ]

    def __str__(self):
        return f"{self.study.slug}:participant {self.pk}"

    def is_finished(self) -> bool:
        """Whether the participant has an outcome that ends their session with a code."""
        return self.completed_at is not None

    def timed_out(self, now=None) -> bool:
        """Whether the study's time limit passed before the participant finished, or they
        answered no trial for the study's idle limit."""
        if self.outcome == self.Outcome.TIMED_OUT:
            return True
        if self.completed_at is not None or self.consented_at is None or self.outcome:
            return False
        now = now or timezone.now()
        limit, idle = self.study.time_limit(), self.study.idle_limit()
        if limit is not None and now - self.consented_at > limit:
            return True
        return idle is not None and now - (self.active_at or self.consented_at) > idle

    def current_trial(self):
        """Return the first unanswered trial, or None."""
        return self.trials.filter(answered_at__isnull=True).order_by("index").first()

    def has_trials(self) -> bool:
        """Return whether the trials were made (from ``by_token``'s count when read so)."""
        n_trials = getattr(self, "n_trials", None)
        return self.trials.exists() if n_trials is None else n_trials > 0

    def excluded(self) -> bool:
        """Return whether the participant failed the study's attention checks."""
        if self.outcome:
            return self.outcome == self.Outcome.FAILED_ATTENTION
        failed = self.trials.filter(kind__in=Trial.CHECK_KINDS, catch_passed=False).count()
        return failed > self.study.max_failed_catch


class TrialManager(models.Manager):
    def mark_shown(self, trial: "Trial") -> None:
        """Record when the trial page was first served; reloads keep the first time."""
        if trial.shown_at is not None:
            return  # a reload: ``trial`` was just read, so the database has it too
        now = timezone.now()
        with cursor() as shown:
            shown.execute(_SHOWN.get(), [prepared(Trial, "shown_at", now), trial.pk])
            if shown.rowcount:
                trial.shown_at = now

    def record_answer(self, trial: "Trial", answer, items, fetches=None) -> bool:
        """Store a checked answer (:class:`~studyapp.participation.answers.Answer`) of a trial once.

        A practice trial keeps only its plays and events: its answer is no judgement. A
        catch, instructed or repeated trial is graded by the study type into
        ``catch_passed``. The participant's ``active_at`` moves on (they are not idle).
        ``items`` are the trial's items as read in this request (with their stimuli);
        ``trial.shown_at`` must be as read in this request (a trial never shown counts
        from now). When this answer is the participant's last, the outcome and the
        completion code are set on ``trial.participant`` too. ``following`` on the
        participant, when set (``TrialItemManager.trials_of``), is the next trial as read
        before: the participant is then only marked active.

        ``fetches(items)``, when given, runs in the transaction once the answer won; if
        it returns True it has set every item's ``fetched`` and ``fetched_at`` under a
        lock, and they are written with the answers (one executemany for the items: an
        UPDATE per item, sent together).

        Return False (and store nothing) when the trial was already answered. The
        conditional UPDATE comes first so two simultaneous submits cannot both win.
        """
        now = timezone.now()
        practice = trial.kind == Trial.Kind.PRACTICE
        trial_answers = {} if practice else answer.trial
        shown_at = trial.shown_at or now
        time_ms = max(0, round((now - shown_at).total_seconds() * 1000))
        with transaction.atomic(), cursor() as writing:
            writing.execute(_ANSWER_TRIAL.get(), [
                prepared(Trial, "answered_at", now), time_ms,
                prepared(Trial, "shown_at", shown_at), prepared(Trial, "answers", trial_answers),
                prepared(Trial, "events", answer.events), trial.pk])
            if not writing.rowcount:
                return False
            trial.answered_at, trial.time_ms, trial.shown_at = now, time_ms, shown_at
            trial.answers, trial.events = trial_answers, answer.events
            for item in items:
                item.plays = answer.plays.get(item.pk, item.plays)
                item.answers = {} if practice else answer.items.get(item.pk, {})
            with_fetches = bool(fetches and fetches(items))
            writing.executemany(
                (_ANSWER_ITEMS_FETCHED if with_fetches else _ANSWER_ITEMS).get(),
                [[prepared(TrialItem, name, getattr(item, name))
                  for name in (ITEM_ANSWER_FIELDS + ITEM_FETCH_FIELDS if with_fetches
                               else ITEM_ANSWER_FIELDS)] + [item.pk] for item in items])
            participant = trial.participant
            if trial.kind in Trial.GRADED_KINDS:
                passed = participant.study.kind.grade(trial, items)
                self.filter(pk=trial.pk).update(catch_passed=passed)
                trial.catch_passed = passed
            following = getattr(participant, "following", None)
            if following and following[0].index == trial.index + 1:
                # The next trial was read unanswered: this was not the last answer.
                writing.execute(_ACTIVE.get(), [prepared(Participant, "active_at", now),
                                               participant.pk])
                participant.active_at = now
                return True
            # One statement: the participant is active now, unless that was their last
            # answer (no unanswered trial left), when they finish.
            unanswered = Trial.objects.filter(participant=OuterRef("pk"), answered_at__isnull=True)
            if Participant.objects.filter(pk=participant.pk).filter(Exists(unanswered)).update(
                    active_at=now):
                participant.active_at = now
            else:
                Participant.objects.finish(participant, now)
        return True


class Trial(models.Model):
    class Kind(models.TextChoices):
        PRACTICE = "practice", "Practice (not a judgement)"
        MAIN = "main", "Main"
        CATCH = "catch", "Catch (a broken clip)"
        INSTRUCTED = "instructed", "Instructed-response check (the text says what to answer)"
        REPEAT = "repeat", "Repeat of an earlier trial"

    # Attention checks (counted against ``max_failed_catch``), and every graded kind.
    CHECK_KINDS = (Kind.CATCH, Kind.INSTRUCTED)
    GRADED_KINDS = (Kind.CATCH, Kind.INSTRUCTED, Kind.REPEAT)

    participant = models.ForeignKey(Participant, on_delete=models.CASCADE, related_name="trials")
    index = models.PositiveIntegerField(help_text="Order in the participant's session.")
    action = models.CharField(max_length=100)
    prompt = models.TextField(blank=True, help_text="The text prompt shown, if any.")
    kind = models.CharField(max_length=16, choices=Kind.choices, default=Kind.MAIN)
    answers = models.JSONField(
        default=dict, blank=True, help_text="Answers on the trial itself, per criterion."
    )
    catch_passed = models.BooleanField(
        null=True, blank=True, help_text="Catch: broken clip spotted; instructed: the answer "
        "asked for given; repeat: answered as before."
    )
    instruction = models.JSONField(
        default=dict, blank=True, help_text="Instructed check: the answer asked for, as the "
        "study type reads it (e.g. {\"position\": 1})."
    )
    repeat_of = models.ForeignKey(
        "self", on_delete=models.CASCADE, null=True, blank=True, related_name="repeats"
    )
    shown_at = models.DateTimeField(null=True, blank=True, help_text="When the page was served.")
    answered_at = models.DateTimeField(null=True, blank=True)
    time_ms = models.PositiveIntegerField(null=True, blank=True, help_text="Time to answer.")
    events = models.JSONField(
        default=list, blank=True,
        help_text="What the page reported: [ms since shown, event, item position] each.",
    )

    objects = TrialManager()

    class Meta:
        ordering = ["participant", "index"]
        constraints = [
            models.UniqueConstraint(fields=["participant", "index"], name="one_trial_per_index")
        ]

    def __str__(self):
        return f"{self.participant}: trial {self.index}"


class TrialItemManager(models.Manager):
    def judged(self):
        return self.filter(role=TrialItem.Role.JUDGED)

    def trials_of(self, participant: "Participant", trial_id: int, and_next: bool = False):
        """Return ``[(trial, items), ...]``: the participant's trial ``trial_id`` and, with
        ``and_next``, the unanswered trial after it, each with its items in screen order
        and their stimuli, in index order, read in one statement (written out:
        :mod:`.rows`). A trial that is not the participant's, or has no items, is not
        there."""
        sql = (_TRIALS_AND_NEXT if and_next else _TRIALS).get()
        params = [participant.pk, trial_id] + ([trial_id, participant.pk] if and_next else [])
        out, trial = [], None
        for item, row_trial, stimulus in read(sql, params, ITEM_ROW, TRIAL_ROW, STIMULUS_ROW):
            if trial is None or row_trial.pk != trial.pk:
                trial = row_trial
                trial.participant = participant
                out.append((trial, []))
            item.trial, item.stimulus = trial, stimulus
            out[-1][1].append(item)
        return out

    def lock_fetches(self, items) -> dict:
        """Return ``{item id: (fetched, fetched_at)}`` of ``items`` as committed, their rows
        locked until the transaction ends (on SQLite, the caller already wrote)."""
        rows = read(_LOCK_FETCHES.get().format(
            ", ".join(["%s"] * len(items))), [item.pk for item in items], FETCH_ROW)
        return {item.pk: (item.fetched, item.fetched_at) for (item,) in rows}

    def record_fetch(self, item_id: int, ext: str, start: int, end: int, size: int) -> None:
        """Record that bytes ``start..end`` (inclusive) of an item's ``ext`` file (its mp4,
        or the in-browser player's payload) were sent whole; the first time the ranges
        of one of its files cover that file, ``fetched_at`` is set."""
        with transaction.atomic():
            if connection.vendor == "sqlite":  # take the write lock first (see StudyManager.lock)
                self.filter(pk=item_id).update(plays=F("plays"))
            item = self.select_for_update().only("fetched", "fetched_at").get(pk=item_id)
            if item.fetched_at is not None:
                return
            fetched = item.fetched if isinstance(item.fetched, dict) else {}
            ranges = merge_ranges([*fetched.get(ext, []), [start, end]])
            fields = {"fetched": {**fetched, ext: ranges}}
            if ranges == [[0, size - 1]]:
                fields["fetched_at"] = timezone.now()
            self.filter(pk=item_id).update(**fields)


class TrialItem(models.Model):
    class Role(models.TextChoices):
        JUDGED = "judged", "Judged"
        REFERENCE = "reference", "Reference shown beside the judged clips"
        EXAMPLE = "example", "Scoring-standard example"

    trial = models.ForeignKey(Trial, on_delete=models.CASCADE, related_name="items")
    stimulus = models.ForeignKey(Stimulus, on_delete=models.PROTECT, related_name="items")
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    role = models.CharField(max_length=16, choices=Role.choices, default=Role.JUDGED)
    position = models.PositiveSmallIntegerField(
        help_text="Place on screen, 0 = first; shown-only clips come after the judged ones."
    )
    required = models.BooleanField(
        default=True, help_text="Must be fetched whole before the trial's answer is taken."
    )
    answers = models.JSONField(default=dict, blank=True, help_text="Answers per criterion.")
    plays = models.PositiveIntegerField(default=0, help_text="Complete plays the page reported.")
    fetched = models.JSONField(
        default=dict, blank=True, help_text="Byte ranges sent whole, per file (mp4, motion)."
    )
    fetched_at = models.DateTimeField(
        null=True, blank=True, help_text="When the whole clip had been sent."
    )

    objects = TrialItemManager()

    class Meta:
        ordering = ["trial", "position"]
        constraints = [
            models.UniqueConstraint(fields=["trial", "position"], name="one_item_per_position"),
            models.UniqueConstraint(
                fields=["trial", "stimulus"], condition=Q(role="judged"),
                name="one_judged_item_per_stimulus",
            ),
        ]

    def __str__(self):
        return f"{self.trial}: position {self.position}"

    def clip_url(self, ext: str = "mp4") -> str:
        """Return the URL of this item's ``mp4``, ``png`` (poster) or ``motion`` (payload)."""
        return reverse("survey:clip", args=[self.token, ext])


class Balance(models.Model):
    """What the balanced planner has handed out in a study's main trials, kept as counts.

    Every start reads how often each judged stimulus has been shown at each position in
    main trials; reading that from every item of the study grows with the study (and runs
    with its row locked), so the counts are kept here: ``counted_to`` is the highest trial
    id whose items are counted, and a start adds its own items under the same lock
    (:class:`Tally`; items of a trial with a higher id found there are counted too). This
    holds as long as main trials are made with their items by a start, under the study's
    lock, and trials and items are deleted only with their participant: nothing else in
    the app makes or deletes them (the admin shows trials and answers read-only).
    Deleting a participant who has main trials deletes the study's row here (a
    ``pre_delete`` receiver, with the study's row locked until the deletion commits): the
    next start counts every item again, once.
    """

    study = models.OneToOneField(Study, on_delete=models.CASCADE, primary_key=True,
                                 related_name="+")
    counted_to = models.BigIntegerField(default=0, help_text="The highest trial id counted.")


class BalanceCount(models.Model):
    """Main-trial items of one judged stimulus at one position, of the trials counted."""

    balance = models.ForeignKey(Balance, on_delete=models.CASCADE, related_name="counts")
    stimulus = models.ForeignKey(Stimulus, on_delete=models.CASCADE, related_name="+")
    position = models.PositiveSmallIntegerField()
    n = models.PositiveIntegerField(default=0)

    class Meta:
        constraints = [
            models.UniqueConstraint(fields=["balance", "stimulus", "position"],
                                    name="one_count_per_place"),
        ]


def shown_counts(study, after: int = 0) -> tuple[Counter, Counter, Counter, int]:
    """Count the main-trial items of judged stimuli of trials with an id above ``after``:
    return them by ``(stimulus id, position)``, by stimulus id and by ``(source,
    position)``, and the highest trial id among them (``after`` if none): one aggregate
    (over every item of the study with ``after=0``; :class:`Tally` keeps the counts so that
    a start reads only the trials since)."""
    rows = (
        TrialItem.objects.judged()
        .filter(stimulus__study=study, trial__kind=Trial.Kind.MAIN, trial_id__gt=after)
        .values("stimulus", "stimulus__source", "position")
        .annotate(n=Count("pk"), last=Max("trial_id"))
        .values_list("stimulus", "stimulus__source", "position", "n", "last")
    )
    places, items, positions = Counter(), Counter(), Counter()
    for stimulus, source, position, n, last in rows:
        places[stimulus, position] += n
        items[stimulus] += n
        positions[source, position] += n
        after = max(after, last)
    return places, items, positions, after


@dataclass
class Tally:
    """How often each judged stimulus has been shown, and each source at each position,
    in the study's main trials: the kept counts (:class:`~studyapp.survey.models.Balance`)
    and the items of any trial after them; read and stored with the study's row locked.

    ``items`` and ``positions`` are what the planner reads (it adds its choices to them);
    :meth:`store` adds a new session's items to the kept counts. Read without the lock (a
    preview, an estimate of the session's length) the three statements are not one
    snapshot: a start committing between them may be counted twice, in an estimate only.
    """

    study: object
    items: Counter
    positions: Counter
    places: Counter  # (stimulus id, position) -> items, the kept counts and the ones since
    unstored: set  # places whose count is not yet what is kept
    counted_to: int
    kept: bool  # whether the study has a Balance row

    @classmethod
    def read(cls, study) -> "Tally":
        balance = Balance.objects.filter(pk=study.pk).first()
        counted_to = balance.counted_to if balance else 0
        places, items, positions, last = shown_counts(study, counted_to)
        unstored = set(places)
        if balance is not None:
            kept = BalanceCount.objects.filter(balance=balance).values_list(
                "stimulus", "stimulus__source", "position", "n")
            for stimulus, source, position, n in kept:
                places[stimulus, position] += n
                items[stimulus] += n
                positions[source, position] += n
        return cls(study, items, positions, places, unstored, last, balance is not None)

    def store(self, trials: list, items: list) -> None:
        """Add a started session (its ``trials`` and their ``items``, saved) to the kept
        counts: one upsert of the places that changed, and the row of what is counted."""
        main = {trial.pk for trial in trials if trial.kind == Trial.Kind.MAIN}
        for item in items:
            if item.role == TrialItem.Role.JUDGED and item.trial_id in main:
                self.places[item.stimulus_id, item.position] += 1
                self.unstored.add((item.stimulus_id, item.position))
        last = max([self.counted_to, *(trial.pk for trial in trials)])
        if self.kept:
            if last != self.counted_to:
                Balance.objects.filter(pk=self.study.pk).update(counted_to=last)
        else:
            Balance.objects.create(study_id=self.study.pk, counted_to=last)
            self.kept = True
        if self.unstored:
            BalanceCount.objects.bulk_create(
                [BalanceCount(balance_id=self.study.pk, stimulus_id=stimulus, position=position,
                              n=self.places[stimulus, position])
                 for stimulus, position in sorted(self.unstored)],
                update_conflicts=True, unique_fields=["balance", "stimulus", "position"],
                update_fields=["n"],
            )
        self.counted_to, self.unstored = last, set()


def forget_balance(sender, instance, **kwargs) -> None:
    """A participant is being deleted: their main-trial items leave the counts, so drop the
    study's kept counts (the study's row locked, as a start holds it) to be counted afresh.
    One without main trials (not started yet, or a blindness audit's, practice only)
    changes no count: nothing is locked or dropped (should a start store main trials for
    them meanwhile, one of the two fails as it commits, on the deferred foreign key: the
    counts are unaffected).

    Deleting participants of several studies in one transaction locks the studies in the
    order of the participants: two such deletions at once may deadlock, and PostgreSQL then
    aborts one (deleting one study's participants at a time avoids it)."""
    if not Trial.objects.filter(participant_id=instance.pk, kind=Trial.Kind.MAIN).exists():
        return
    Study.objects.lock(instance.study_id)
    Balance.objects.filter(pk=instance.study_id).delete()


class ResponseManager(models.Manager):
    def get_queryset(self):
        return (
            super()
            .get_queryset()
            .filter(trial__answered_at__isnull=False, role=TrialItem.Role.JUDGED)
            .exclude(trial__kind=Trial.Kind.PRACTICE)
        )


class Response(TrialItem):
    """An answered judged trial item: one judgement (a view for the admin)."""

    objects = ResponseManager()

    class Meta:
        proxy = True
        ordering = ["-trial__answered_at", "position"]


# --- the answer's statements, written out (:mod:`.rows`) ------------------------------------

PARTICIPANT_ROW = Columns(Participant, "p")
ITEM_ROW = Columns(TrialItem, "i")
TRIAL_ROW = Columns(Trial, "t")
STIMULUS_ROW = Columns(Stimulus, "s")
FETCH_ROW = Columns(TrialItem, "i", ["id", "fetched", "fetched_at"])
ITEM_ANSWER_FIELDS = ["plays", "answers"]
ITEM_FETCH_FIELDS = ["fetched", "fetched_at"]


def _by_token_sql() -> str:
    """The statement of ``ParticipantManager.by_token``; it also reads the study's
    ``version``: a process keeping the study row checks it for free."""
    t, s = quote(Trial._meta.db_table), quote(Study._meta.db_table)
    trials = f"FROM {t} WHERE {t}.{quote('participant_id')} = p.{quote('id')}"
    return (
        f"SELECT {PARTICIPANT_ROW.sql()}, "
        f"(SELECT {s}.{quote('version')} FROM {s} WHERE {s}.{quote('id')} = "
        f"p.{quote('study_id')}), "
        f"(SELECT COUNT(*) {trials}), "
        f"(SELECT COUNT(*) {trials} AND {t}.{quote('kind')} = '{Trial.Kind.PRACTICE}'), "
        f"(SELECT {t}.{quote('id')} {trials} AND {t}.{quote('answered_at')} IS NULL "
        f"ORDER BY {t}.{quote('index')} LIMIT 1) "
        f"FROM {quote(Participant._meta.db_table)} p "
        f"WHERE p.{quote('study_id')} = %s AND p.{quote('token')} = %s"
    )


def _trials_sql(and_next: bool) -> str:
    item_table, trial_table = quote(TrialItem._meta.db_table), quote(Trial._meta.db_table)
    index, answered = quote("index"), quote("answered_at")
    following = (
        f" OR (t.{answered} IS NULL AND t.{index} = (SELECT u.{index} + 1 FROM {trial_table} u "
        f"WHERE u.{quote('id')} = %s AND u.{quote('participant_id')} = %s))"
    ) if and_next else ""
    return (
        f"SELECT {ITEM_ROW.sql()}, {TRIAL_ROW.sql()}, {STIMULUS_ROW.sql()} "
        f"FROM {item_table} i "
        f"INNER JOIN {trial_table} t ON i.{quote('trial_id')} = t.{quote('id')} "
        f"INNER JOIN {quote(Stimulus._meta.db_table)} s "
        f"ON i.{quote('stimulus_id')} = s.{quote('id')} "
        f"WHERE t.{quote('participant_id')} = %s AND (t.{quote('id')} = %s{following}) "
        f"ORDER BY t.{index}, i.{quote('position')}"
    )


def _update_sql(model, names, where="") -> str:
    assignments = ", ".join(f"{quote(model._meta.get_field(name).column)} = %s"
                            for name in names)
    return (f"UPDATE {quote(model._meta.db_table)} SET {assignments} "
            f"WHERE {quote('id')} = %s{where}")


def _lock_fetches_sql() -> str:
    lock = " FOR UPDATE" if connection.features.has_select_for_update else ""
    return (f"SELECT {FETCH_ROW.sql()} FROM {quote(TrialItem._meta.db_table)} i "
            f"WHERE i.{quote('id')} IN ({{}}) ORDER BY i.{quote('id')}{lock}")


_BY_TOKEN = Statements(_by_token_sql)
_FIND = Statements(lambda: (
    f"SELECT {PARTICIPANT_ROW.sql()} FROM {quote(Participant._meta.db_table)} p "
    f"WHERE p.{quote('study_id')} = %s AND p.{quote('external_key')} = %s LIMIT 1"))
_TRIALS = Statements(lambda: _trials_sql(False))
_TRIALS_AND_NEXT = Statements(lambda: _trials_sql(True))
_ANSWER_TRIAL = Statements(lambda: _update_sql(
    Trial, ["answered_at", "time_ms", "shown_at", "answers", "events"],
    f" AND {quote('answered_at')} IS NULL"))
_ANSWER_ITEMS = Statements(lambda: _update_sql(TrialItem, ITEM_ANSWER_FIELDS))
_ANSWER_ITEMS_FETCHED = Statements(lambda: _update_sql(
    TrialItem, ITEM_ANSWER_FIELDS + ITEM_FETCH_FIELDS))
_SHOWN = Statements(lambda: _update_sql(
    Trial, ["shown_at"], f" AND {quote('shown_at')} IS NULL"))
_ACTIVE = Statements(lambda: _update_sql(Participant, ["active_at"]))
_LOCK_FETCHES = Statements(_lock_fetches_sql)
