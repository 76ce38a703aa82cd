"""Which restarts the estimate comes from (train/selection.py): first the score, then the loss."""
from __future__ import annotations

import math

from fitode.train.result import RunRecord
from fitode.train.selection import SCORE_MARGIN, select_runs


def _run(i: int, loss: float, score: float | None = None, status: str = "ok", steps: int = 100) -> RunRecord:
    return RunRecord(index=i, seed=i, init={}, final={}, loss=loss, steps=steps, status=status, score=score)


def test_the_score_decides_before_the_loss():
    # the harmonic trap: a folded latent (score 0.1) with the lowest loss must not be chosen
    runs = [_run(0, 0.010, score=0.95), _run(1, 0.001, score=0.10), _run(2, 0.012, score=0.97)]
    assert select_runs(runs, 1.5) == [0, 2]


def test_runs_within_the_score_margin_are_kept_and_judged_by_loss():
    top = 0.9
    runs = [_run(0, 0.010, score=top), _run(1, 0.011, score=top - SCORE_MARGIN / 2),
            _run(2, 0.010, score=top - 2 * SCORE_MARGIN), _run(3, 0.020, score=top)]
    # run 2 scores too low; run 3's loss is more than 1.5x the best of the rest
    assert select_runs(runs, 1.5) == [0, 1]
    assert select_runs(runs, 2.5) == [0, 1, 3]


def test_unscored_runs_are_judged_by_their_loss_alone():
    runs = [_run(0, 0.010, score=None), _run(1, 0.012, score=0.2), _run(2, 0.009, score=math.nan)]
    assert select_runs(runs, 1.5) == [0, 1, 2]


def test_failed_unstarted_and_non_finite_runs_are_never_selected():
    runs = [_run(0, 0.02), _run(1, 0.01, status="failed"), _run(2, 0.01, steps=0), _run(3, math.inf),
            _run(4, 0.02, status="interrupted")]
    assert select_runs(runs, 1.5) == [0]
    # an interrupted fit may fall back to what its restarts reached
    assert select_runs(runs, 1.5, statuses=("ok", "interrupted")) == [0, 4]
    assert select_runs([_run(0, 0.01, status="failed")], 1.5) == []


def test_a_failed_run_with_a_high_score_does_not_raise_the_bar():
    # scores are compared among the runs that can be selected only
    runs = [_run(0, 0.01, score=0.5), _run(1, 0.005, score=0.99, status="failed")]
    assert select_runs(runs, 1.5) == [0]
