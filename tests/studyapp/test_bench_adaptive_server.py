"""benchmarks/bench_adaptive_server.py at a tiny size: one adaptive and one balanced study
taken at once by bots of known strengths (clips varying) through the live server's pages,
the background job recomputing the design and checking the stop, the report's intervals
measured. Its figures are not checked (too few judgements to mean anything), only that
every step still runs."""

import pytest

from benchmarks import bench_adaptive_server as bench

pytestmark = pytest.mark.django_db(transaction=True)


def test_the_benchmark_runs_both_designs_through_the_real_pages(media_root, live_server,
                                                                  tmp_path):
    clips = bench.write_clips(tmp_path / "clips", clips=2)
    results = bench.run_pair(live_server.url, clips, seed=1, width=4.0, trials=4, every=8,
                             concurrency=3, budget=48, time_limit=45, bootstrap=20)
    assert [r["design"] for r in results] == ["adaptive", "balanced"]
    for result in results:
        assert result["ended_by"] in ("stopped", "budget")
        assert result["judgements_in_the_end"] >= 8 and result["participants"] >= 2
        assert not result["reached"] or result["judgements_at_stop"] >= 8
        (interval,) = result["intervals"]  # the top two
        assert interval["ci_low"] <= interval["difference"] <= interval["ci_high"]
        assert {"truth_population", "truth_these_clips"} <= set(interval)
    from studyapp.survey.models import Study

    adaptive = Study.objects.get(slug=results[0]["study"])
    assert adaptive.sampling.get("pairs") and "stop" in adaptive.sampling  # the job ran
    rows = bench.summary(results)
    assert "| top_two (4.0) | adaptive |" in bench.table(rows, "top_two", 4.0)


def test_a_batch_is_part_of_the_adaptive_settings_only_when_asked(media_root, tmp_path):
    clips = bench.write_clips(tmp_path / "clips", clips=1)
    batched = bench.make_study("batched", "adaptive", clips, "order", 0.7, 4, 10, batch=20)
    plain = bench.make_study("plain", "adaptive", clips, "order", 0.7, 4, 10)
    assert batched.adaptive == {"every": 10, "target": "order", "batch": 20}
    assert plain.adaptive == {"every": 10, "target": "order"}
    assert batched.stop_when == {"interval_width": 0.7}


def test_replicates_run_at_once_and_each_is_yielded_as_it_ends(monkeypatch):
    import threading

    together = threading.Barrier(2, timeout=10)  # broken (an error) unless two run at once
    seen = []

    def run_pair(url, clips, seed, **settings):
        together.wait()
        seen.append(settings)
        return [{"seed": seed, "design": design} for design in bench.DESIGNS]

    monkeypatch.setattr(bench, "run_pair", run_pair)
    pairs = list(bench.run_replicates("http://x", [], [1, 2, 3, 4], parallel=2, width=0.7))
    assert sorted(pair[0]["seed"] for pair in pairs) == [1, 2, 3, 4]
    assert all(len(pair) == 2 for pair in pairs) and seen == [{"width": 0.7}] * 4


def test_the_table_is_printed_again_from_a_runs_json(tmp_path, capsys):
    import json

    def study(seed, design, at_stop, covers):
        interval = {"covers_population": covers, "covers_these_clips": True}
        return {"seed": seed, "design": design, "reached": True, "judgements_at_stop": at_stop,
                "judgements_in_the_end": at_stop + 5, "report_width": 1.0,
                "covered_population": covers, "covered_these_clips": True,
                "intervals": [interval, dict(interval, covers_population=True)]}

    run = {"args": {"target": "order", "width": "0.7"},
           "studies": [study(2, "balanced", 200, True), study(1, "adaptive", 100, False),
                       study(1, "balanced", 200, True), study(2, "adaptive", 140, True)]}
    path = tmp_path / "run.json"
    path.write_text(json.dumps(run))
    assert bench.main(["--summarise", str(path)]) == 0
    out = capsys.readouterr().out
    assert ("| order (0.7) | adaptive | 2/2 | 100, 140 | 120 | 120 | -40% | -40% | 125 | 1.00 | "
            "1/2 | 2/2 | 0.750 (4) | 1.000 (4) |") in out
