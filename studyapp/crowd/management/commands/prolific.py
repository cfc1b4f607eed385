import json
import math

import pandas as pd
from django.core.management.base import BaseCommand, CommandError

from analysis import plan

from studyapp.survey import site
from studyapp.results.export import get_study
from studyapp.survey.models import Participant, Study
from studyapp.crowd.prolific import bonus, draft, review
from studyapp.crowd.prolific.client import Client, ProlificError

APPROVE_BATCH = 100  # submission ids per bulk-approve request, sent one after another


class Command(BaseCommand):
    help = (
        "Run a study on Prolific through its API (token from PROLIFIC_TOKEN): create a draft "
        "Prolific study from ours, publish or stop it, list its submissions beside our "
        "participants, review them by our exclusions (approve, ask for a return or reject) "
        "and pay bonuses. See README, 'Crowd platforms'."
    )

    def add_arguments(self, parser):
        sub = parser.add_subparsers(dest="subcommand", required=True, metavar="SUBCOMMAND")

        def command(name, text):
            p = sub.add_parser(name, help=text, description=text)
            p.add_argument("--study", required=True, metavar="SLUG", help="Our study.")
            return p

        create = command("create", "Create a draft study on Prolific from ours and store its "
                                   "id (and completion codes) in the study's crowd settings.")
        create.add_argument("--base-url", help="Where our site is served (default: "
                            "STUDY_BASE_URL, else the address `demo` served on).")
        create.add_argument("--places", type=int, help="Participants to recruit (default: "
                            "the study's max_participants).")
        create.add_argument("--minutes", type=int, help="Estimated completion time (default: "
                            "the study's own: estimated from its trials and clips, the median of its completed "
                            "sessions once 5 have completed; as the consent text says).")
        create.add_argument("--reward-cents", type=int, help="Reward per participant in "
                            "cents of the account's currency (default: --minutes at "
                            "--hourly-cents an hour).")
        create.add_argument("--hourly-cents", type=int, default=draft.DEFAULT_HOURLY_CENTS,
                            help="Hourly rate of the default reward (default %(default)s; "
                                 "check Prolific's current minimum).")
        create.add_argument("--description", default="", help="Shown on Prolific (default: "
                            "the study's consent text).")
        create.add_argument("--devices", default=",".join(draft.DEVICES),
                            help="Devices allowed (default %(default)s).")
        create.add_argument("--review-completed", action="store_true",
                            help="Completed submissions wait for `review` instead of being "
                                 "approved automatically.")
        create.add_argument("--screen-out-reward-cents", type=int, help="Pay people screened "
                            "out this much (Prolific's fixed screen-out payment) instead of "
                            "asking them to return.")
        create.add_argument("--plan", metavar="PLAN.CSV",
                            help="Take places and minutes from a plan's recommendation "
                                 "(`plan --out DIR` or the admin's Plan page writes plan.csv); "
                                 "--places and --minutes still win.")
        create.add_argument("--plan-target", type=float, default=0.8,
                            help="Power the plan's recommendation must reach (default 0.8).")
        create.add_argument("--dry-run", action="store_true",
                            help="Print the JSON it would send; send and store nothing.")
        create.add_argument("--force", action="store_true",
                            help="Create another Prolific study although one is stored.")

        command("publish", "Publish the Prolific study (participants can take it).")
        command("stop", "Stop the Prolific study (no new participants).")
        listing = command("submissions", "List the Prolific study's submissions beside our "
                                         "participants' outcomes.")
        listing.add_argument("--json", action="store_true", help="One JSON object per line.")

        check = command("review", "Approve completed submissions and ask failed-attention "
                                  "ones to return (or reject them), by our exclusions; flag "
                                  "our participants whose ids Prolific does not know.")
        failed = check.add_mutually_exclusive_group()
        failed.add_argument("--return-failed", dest="reject_failed", action="store_false",
                            help="Ask participants who failed the attention checks to return "
                                 "their submission (the default).")
        failed.add_argument("--reject-failed", dest="reject_failed", action="store_true",
                            help="Reject them instead (category FAILED_CHECK), if they "
                                 "failed at least two checks (Prolific's rule; with fewer, "
                                 "a return is asked for).")
        check.set_defaults(reject_failed=False)
        check.add_argument("--reject-message", default=review.DEFAULT_REJECT_MESSAGE,
                           help="What a rejected participant reads (at least 100 characters).")
        check.add_argument("--max-failed-catch", type=int, help="Exclude participants who "
                           "failed more than N attention checks, catch and instructed "
                           "trials (default: the study's own rule).")
        check.add_argument("--max-failed-repeats", type=int, help="Also exclude participants "
                           "who answered more than N repeated trials differently.")
        check.add_argument("--dry-run", action="store_true",
                           help="Show what it would do; send nothing.")

        pay = command("bonus", "Pay bonuses through Prolific's bulk bonus (set up, then pay).")
        who = pay.add_mutually_exclusive_group(required=True)
        who.add_argument("--csv", metavar="FILE", help="Lines participant_id,amount with the "
                         "amount in the study's currency, e.g. 60ffe5c8371090c7041d43f8,0.50.")
        who.add_argument("--amount-cents", type=int, help="Pay this many cents to everyone "
                         "with --outcome.")
        pay.add_argument("--outcome", choices=Participant.Outcome.values,
                         help="With --amount-cents: whose submissions get the bonus.")
        pay.add_argument("--max-amount-cents", type=int, default=2000,
                         help="Refuse any single bonus above this (default %(default)s).")
        pay.add_argument("--again", action="store_true",
                         help="Also pay people who already have a bonus in this study.")
        pay.add_argument("--dry-run", action="store_true", help="Show the bonuses; pay nothing.")

    def handle(self, *args, subcommand, study, **options):
        study = get_study(study)
        try:
            getattr(self, f"do_{subcommand}")(study, options)
        except ProlificError as error:
            raise CommandError(str(error)) from None

    def _from_plan(self, path, target, places, minutes):
        """Return places and minutes from the plan's recommended design (given ones kept)."""
        try:
            frame = pd.read_csv(path)
        except (OSError, ValueError) as error:
            raise CommandError(f"--plan {path}: cannot read it as a plan table ({error}); "
                               f"write one with `manage.py plan --out DIR`") from None
        missing = {"participants", "clips", "power"} - set(frame.columns)
        if missing:
            raise CommandError(f"--plan {path} has no column(s) {', '.join(sorted(missing))}; "
                               f"write one with `manage.py plan --out DIR`")
        best = plan.recommend(frame, target)
        if not best["reached"]:
            self.stderr.write(f"Warning: no design of the plan reaches {target:.0%} power; "
                              f"taking the most powerful ({best['power']:.0%}).")
        self.stdout.write(f"From the plan: {int(best['participants'])} participants and "
                          f"{int(best['clips'])} clips per source and condition "
                          f"({best['power']:.0%} power); build that many clips.")
        if places is None:
            places = int(best["participants"])
        if minutes is None and "minutes" in best:
            minutes = int(math.ceil(best["minutes"]))
        return places, minutes

    # Subcommands

    def do_create(self, study, options):
        crowd = dict(study.crowd or {})
        if crowd.get("platform") not in (None, "", "none", "prolific"):
            raise CommandError(f"study {study.slug} is set up for platform "
                               f"{crowd['platform']!r}: a Prolific study needs platform "
                               f"prolific (or none) in its crowd settings")
        if crowd.get("prolific_study_id") and not options["force"] and not options["dry_run"]:
            raise CommandError(f"study {study.slug} already has Prolific study "
                               f"{crowd['prolific_study_id']}; --force creates another")
        base = (options["base_url"] or site.base_url()).rstrip("/")
        places, minutes = options["places"], options["minutes"]
        if options.get("plan"):
            places, minutes = self._from_plan(options["plan"], options["plan_target"], places,
                                              minutes)
        codes, made = draft.fill_codes(study)
        choices = draft.DraftOptions(
            base_url=base, places=places, minutes=minutes,
            reward_cents=options["reward_cents"], hourly_cents=options["hourly_cents"],
            description=options["description"],
            devices=tuple(d.strip() for d in options["devices"].split(",") if d.strip()),
            review_completed=options["review_completed"],
            screen_out_reward_cents=options["screen_out_reward_cents"])
        try:
            payload = draft.draft_payload(study, codes, choices)
        except ValueError as error:
            raise CommandError(str(error)) from None
        if base.startswith("http://"):
            self.stderr.write(f"Warning: participants reach the study at {base}, which is not "
                              f"https; pass --base-url https://... (or set STUDY_BASE_URL) "
                              f"for a public study.")
        if options["minutes"] is None:
            self.stdout.write(f"Duration: {study.duration().describe()}.")
        if options["reward_cents"] is None:
            minutes = payload["estimated_completion_time"]
            self.stdout.write(f"Reward {payload['reward']} cents: {minutes} minutes at "
                              f"{options['hourly_cents']} cents an hour (--reward-cents sets it).")
        limit = payload.get("maximum_allowed_time")
        if limit is None:
            self.stdout.write("The study has no time limit (crowd.time_limit_minutes: null): "
                              "Prolific applies its own maximum time.")
        elif "time_limit_minutes" not in (study.crowd or {}):
            self.stdout.write(f"Time limit {limit} minutes (3 x the estimated "
                              f"{payload['estimated_completion_time']}, at least Prolific's "
                              f"minimum): sent as Prolific's maximum allowed time and stored "
                              f"as crowd.time_limit_minutes, so both time people out alike.")
        if options["dry_run"]:
            if made:
                self.stdout.write(f"Would generate completion codes for {', '.join(made)} "
                                  f"and store them in the study's crowd settings.")
            self.stdout.write(json.dumps(payload, indent=2))
            self.stdout.write("Dry run: nothing was sent to Prolific or stored.")
            return
        created = Client.from_env().create_study(payload)
        crowd.update(platform="prolific", codes=codes, prolific_study_id=created["id"])
        crowd.setdefault("time_limit_minutes", limit)
        _save_crowd(study, crowd)
        for warning in study.crowd_warnings():
            self.stderr.write(f"Warning: {warning}")
        if made:
            self.stdout.write(f"Generated completion codes for {', '.join(made)} and stored "
                              f"them in the study's crowd settings: "
                              + ", ".join(f"{o} {codes[o]}" for o in made) + ".")
        self.stdout.write(f"Created draft Prolific study {created['id']} "
                          f"({created.get('status', 'UNPUBLISHED')}) for {study.slug}: "
                          f"{payload['total_available_places']} places, "
                          f"{payload['reward']} cents, link {payload['external_study_url']}")
        self.stdout.write(f"Check it on Prolific, then: manage.py prolific publish "
                          f"--study {study.slug}")

    def do_publish(self, study, options):
        if study.status != Study.Status.OPEN:
            raise CommandError(f"study {study.slug} is {study.status}: participants coming "
                               f"from Prolific would find it closed; open it first (admin)")
        self._transition(study, "PUBLISH")

    def do_stop(self, study, options):
        self._transition(study, "STOP")

    def _transition(self, study, action):
        prolific_id = _prolific_id(study)
        answer = Client.from_env().transition_study(prolific_id, action)
        self.stdout.write(f"Prolific study {prolific_id} of {study.slug}: {action} sent; "
                          f"status {(answer or {}).get('status', 'unknown')}.")

    def do_submissions(self, study, options):
        prolific_id = _prolific_id(study)
        submissions = Client.from_env().study_submissions(prolific_id)
        people = review.participant_index(study)
        rows = []
        for s in submissions:
            row = people.get(str(s.get("participant_id", "")).lower())
            rows.append({
                "submission": s.get("id"), "participant_id": s.get("participant_id"),
                "status": s.get("status"), "started_at": s.get("started_at"),
                "completed_at": s.get("completed_at"), "study_code": s.get("study_code"),
                "return_requested": s.get("return_requested"),
                "participant": int(row["participant"]) if row else None,
                "outcome": (row.get("outcome") or "taking part") if row else "unknown",
            })
        if options["json"]:
            for row in rows:
                self.stdout.write(json.dumps(row))
            return
        self.stdout.write(f"{len(rows)} submission(s) of Prolific study {prolific_id} "
                          f"({study.slug}):")
        header = ("participant_id", "status", "started_at", "completed_at", "study_code",
                  "participant", "outcome")
        self.stdout.write("\t".join(header))
        for row in rows:
            self.stdout.write("\t".join("" if row[k] is None else str(row[k]) for k in header))
        for row, why in review.unknown_ids(study, submissions):
            self.stdout.write(f"flagged: participant {int(row['participant'])}: {why}")

    def do_review(self, study, options):
        message = options["reject_message"]
        if options["reject_failed"] and len(message) < 100:
            raise CommandError(f"--reject-message has {len(message)} characters; Prolific "
                               f"wants at least 100 in a rejection message")
        try:
            config = review.Rules(
                max_failed_catch=(study.max_failed_catch if options["max_failed_catch"] is None
                                  else options["max_failed_catch"]),
                max_failed_repeats=options["max_failed_repeats"])
        except ValueError as error:
            raise CommandError(str(error)) from None
        prolific_id = _prolific_id(study)
        client = Client.from_env()
        submissions = client.study_submissions(prolific_id)
        decisions = review.plan(study, submissions, config, options["reject_failed"])
        verb = "would " if options["dry_run"] else ""
        counts = {}
        for d in decisions:
            counts[d.action] = counts.get(d.action, 0) + 1
            who = f"participant {d.participant}" if d.participant is not None else "unknown"
            note = f" [{d.note}]" if d.note and d.action != review.NOTHING else ""
            label = {review.NOTHING: "nothing to do", review.LEAVE: "left alone"}.get(
                d.action, f"{verb}{d.action}")
            self.stdout.write(f"{label}: {d.prolific_id} ({who}, submission {d.submission_id}"
                              f", {d.submission.get('status')}): {d.why}{note}")
        for row, why in review.unknown_ids(study, submissions):
            self.stdout.write(f"flagged: participant {int(row['participant'])} "
                              f"(outcome {review.text(row.get('outcome')) or 'taking part'}): "
                              f"{why}; a made-up id? Their answers stay in the export with "
                              f"their ids.")
        if not options["dry_run"]:
            self._act(client, decisions, message)
        done = ", ".join(f"{counts.get(a, 0)} {a}" for a in
                         (review.APPROVE, review.RETURN, review.REJECT))
        rest = counts.get(review.NOTHING, 0) + counts.get(review.LEAVE, 0)
        if options["dry_run"]:
            self.stdout.write(f"Dry run: would {done}; {rest} untouched. Nothing was sent.")
        else:
            self.stdout.write(f"Reviewed {len(decisions)} submission(s): {done}; "
                              f"{rest} untouched.")

    def _act(self, client, decisions, message):
        """Send the decisions; if one fails, say so (a second run finishes the rest)."""
        approve = [d.submission_id for d in decisions if d.action == review.APPROVE]
        try:
            for start in range(0, len(approve), APPROVE_BATCH):
                client.bulk_approve(approve[start:start + APPROVE_BATCH])
            for d in decisions:
                if d.action == review.RETURN:
                    reason = review.RETURN_REASON.get(d.outcome, review.FAILED_REASON)
                    client.request_return(d.submission_id, [reason])
                elif d.action == review.REJECT:
                    client.transition_submission(d.submission_id, "REJECT", message=message,
                                                 rejection_category=review.REJECT_CATEGORY)
        except ProlificError as error:
            raise CommandError(f"{error} The review stopped there; run it again to finish "
                               f"(what was done is not done twice).") from None

    def do_bonus(self, study, options):
        if options["amount_cents"] is not None and not options["outcome"]:
            raise CommandError("--amount-cents needs --outcome (e.g. --outcome completed)")
        if options["csv"] and options["outcome"]:
            raise CommandError("--outcome goes with --amount-cents; a --csv file names its "
                               "participants itself")
        prolific_id = _prolific_id(study)
        client = Client.from_env()
        submissions = client.study_submissions(prolific_id)
        try:
            if options["csv"]:
                bonuses = bonus.read_csv(options["csv"], options["max_amount_cents"])
            else:
                bonuses = self._bonuses_by_outcome(study, submissions, options)
            bonus.check_took_part(bonuses, submissions)
        except bonus.BonusError as error:
            raise CommandError(str(error)) from None
        if not options["again"]:
            for pid, paid in bonus.paid_before(client, bonuses, submissions).items():
                self.stdout.write(f"skipped {pid}: already has bonus payment(s) {paid} in this "
                                  f"study (--again pays again)")
                del bonuses[pid]
        if not bonuses:
            self.stdout.write("No bonuses to pay.")
            return
        text = bonus.csv_bonuses(bonuses)
        total = sum(bonuses.values())
        self.stdout.write(f"{len(bonuses)} bonus(es), {bonus.amount_text(total)} in all "
                          f"(before Prolific's fees):\n{text}")
        if options["dry_run"]:
            self.stdout.write("Dry run: nothing was set up or paid.")
            return
        setup = client.set_up_bonuses(prolific_id, text)
        self.stdout.write(f"Set up bulk bonus payment {setup.get('id')}: amount "
                          f"{setup.get('amount')}, fees {setup.get('fees')}, total "
                          f"{setup.get('total_amount')} (Prolific's figures, in cents).")
        answer = client.pay_bonuses(setup["id"])
        self.stdout.write(f"Paid: {answer if isinstance(answer, str) else json.dumps(answer)}")

    def _bonuses_by_outcome(self, study, submissions, options):
        cents = options["amount_cents"]
        if not 0 < cents <= options["max_amount_cents"]:
            raise bonus.BonusError(f"--amount-cents {cents} must be between 1 and "
                                   f"{options['max_amount_cents']} (--max-amount-cents)")
        people = review.participant_index(study)
        chosen = {}
        for s in submissions:
            pid = str(s.get("participant_id", "")).lower()
            row = people.get(pid)
            wanted = row and row.get("outcome") == options["outcome"]
            if wanted and s.get("status") in bonus.PAYABLE:
                chosen[pid] = cents
        if not chosen:
            raise bonus.BonusError(f"no approved or awaiting-review submission of a participant "
                                   f"with outcome {options['outcome']}")
        return chosen


def _prolific_id(study) -> str:
    prolific_id = (study.crowd or {}).get("prolific_study_id")
    if not prolific_id:
        raise CommandError(f"study {study.slug} has no Prolific study yet: run `manage.py "
                           f"prolific create --study {study.slug}`, or put the id of one made "
                           f"on Prolific in its crowd settings (prolific_study_id)")
    return prolific_id


def _save_crowd(study, crowd: dict) -> None:
    """Store ``crowd`` on ``study`` after the same checks as the admin's."""
    study.crowd = crowd
    problem = study.crowd_problem()  # the admin's checks: settings, a code per outcome
    if problem:
        raise CommandError(f"cannot store the crowd settings: {problem}")
    study.save(update_fields=["crowd"])

