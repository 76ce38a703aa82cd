"""fitode.Result: the verbs a notebook uses, on one small fit of a generated lamp."""
from __future__ import annotations

import csv
import json
import sys
import types

import numpy as np
import pytest

import fitode
from fitode.examples.make_example import decay_values, render_glow, write_mp4
from fitode.result import Result

EQ = "I' = -gamma*I"


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    folder = tmp_path_factory.mktemp("result")
    video = write_mp4(folder / "glow.mp4", render_glow(decay_values(40, 10.0, 0.5), size=16), 10.0)
    return fitode.fit(video, eq=EQ, restarts=2, stride=1, light="linear", progress=False)


def test_print_shows_the_command_lines_table_not_the_history(result, capsys):
    assert isinstance(result, Result) and fitode.Result is Result
    print(result)
    out = capsys.readouterr().out
    assert out.startswith("estimates (mean over") and "gamma" in out and result.verdicts["gamma"]["verdict"].upper() in out
    assert out.strip() == result.summary()
    assert "history" not in out and len(out.splitlines()) < 12  # the training history is not printed
    assert "gamma=" in repr(result) and len(repr(result)) < 200


def test_the_html_table_has_each_constant_and_its_verdict(result):
    page = result._repr_html_()
    assert page.count("<tr>") == 2 and "<td>gamma</td>" in page
    assert f"<td>{result.verdicts['gamma']['verdict'].upper()}</td>" in page


def test_confidence_interval_at_95_is_the_fits_and_other_levels_scale_it(result):
    est = result.parameters["gamma"]
    assert result.confidence_interval("gamma") == pytest.approx(tuple(est.interval))
    lo68, hi68 = result.confidence_interval("gamma", level=0.68)
    lo99, hi99 = result.confidence_interval("gamma", level=0.99)
    assert lo99 < est.interval[0] < lo68 < est.value < hi68 < est.interval[1] < hi99
    # 0.68 is about one sigma: the 95% half width over 1.96 (and 0.994 of it)
    assert est.value - lo68 == pytest.approx((est.value - est.interval[0]) * 0.9945 / 1.96, rel=1e-3)
    with pytest.raises(fitode.ConfigError, match="no constant 'gama'; the constants are gamma"):
        result.confidence_interval("gama")
    with pytest.raises(fitode.ConfigError, match="level must be"):
        result.confidence_interval("gamma", level=95)


def test_to_dataframe_says_in_one_line_that_pandas_is_missing(result, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # as where pandas is not installed
    with pytest.raises(ImportError) as err:
        result.to_dataframe()
    assert "needs pandas, which is not installed" in str(err.value) and "\n" not in str(err.value)


def test_to_dataframe_gives_estimates_csvs_rows(result, monkeypatch):
    made = {}

    class Frame:  # pandas' DataFrame, as far as to_dataframe uses it
        def __init__(self, rows, columns):
            made.update(rows=rows, columns=columns)

        def set_index(self, key):
            made["index"] = key
            return self

    monkeypatch.setitem(sys.modules, "pandas", types.SimpleNamespace(DataFrame=Frame))
    result.to_dataframe()
    from fitode.tables import ESTIMATE_COLUMNS
    assert made["columns"] == list(ESTIMATE_COLUMNS) and made["index"] == "constant"
    (row,) = made["rows"]
    assert row[0] == "gamma" and row[1] == result.parameters["gamma"].value
    assert row[2:4] == result.parameters["gamma"].interval and row[7] == result.verdicts["gamma"]["verdict"]


def test_plot_draws_the_state_and_the_fit_on_one_figure(result, tmp_path):
    fig = result.plot(tmp_path / "fit.png")
    (ax,) = fig.axes
    lines = ax.get_lines()
    fitted = result.rollout[:, 0]  # the trajectory over the frames it was fitted on
    assert np.allclose(lines[0].get_ydata(), result.latent[:, 0])
    assert np.allclose(lines[1].get_ydata(), fitted[np.isfinite(fitted)])
    assert (tmp_path / "fit.png").stat().st_size > 1000


def test_save_writes_the_folder_and_load_reads_it_back(result, tmp_path):
    folder = result.save(tmp_path / "run")
    names = {p.name for p in folder.iterdir()}
    assert names >= {"result.json", "fit.json", "estimates.csv", "track.csv", "latent.png"}
    # the lamp's light is measured and fitted directly: no training, so no training pictures
    assert result.meta["direct"] and not names & {"params.png", "loss.png"}
    report = json.loads((folder / "result.json").read_text())
    assert report["status"] == "complete" and sorted(report["files"]) == sorted(names)
    assert report["parameters"]["gamma"]["interval"] == result.parameters["gamma"].interval
    (row,) = csv.DictReader((folder / "estimates.csv").open())
    assert float(row["value"]) == result.parameters["gamma"].value and row["verdict"] == result.verdicts["gamma"]["verdict"]
    back = Result.load(folder)
    assert isinstance(back, Result) and back.values == result.values and back.summary() == result.summary()
    with pytest.raises(fitode.FitodeError, match="not empty"):  # nothing is overwritten
        result.save(folder)


def test_numpys_warnings_become_one_line_each_not_terminal_noise(recwarn):
    from fitode.numeric_warnings import kept
    with kept() as numeric:
        for _ in range(3):
            np.exp(np.array([1000.0]))
        np.sqrt(np.array([-1.0]))
    lines = numeric.lines()
    assert len(lines) == 2 and lines[0].startswith("numpy warned 3 times during the fit: overflow encountered in exp")
    assert "invalid value encountered in sqrt" in lines[1]
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]  # none reached the terminal


def test_progress_goes_only_to_a_terminal_unless_asked(capfd):
    frames = render_glow(decay_values(30, 10.0, 0.5), size=12)
    fitode.fit(frames, 0.1, eq=EQ, restarts=1, max_steps=20, window=6, light="linear")  # stderr here is no terminal
    assert capfd.readouterr().err == ""
    fitode.fit(frames, 0.1, eq=EQ, restarts=1, max_steps=20, window=6, light="linear", progress=True)  # asked
    err = capfd.readouterr().err
    assert "1 restart" in err and "%|" in err


def test_a_ctrl_c_after_training_returns_the_estimates_marked(monkeypatch):
    import fitode.api

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt  # as Ctrl-C lands while the intervals are made
    monkeypatch.setattr(fitode.api, "_intervals", interrupted)
    frames = render_glow(decay_values(30, 10.0, 0.5), size=12)
    r = fitode.fit(frames, 0.1, eq=EQ, restarts=1, max_steps=20, window=6, light="linear", progress=False)
    assert r.meta["stopped"] == {"stage": "intervals",
                                 "undone": ["the 95% interval", "the checks behind the verdict"]}
    assert r.parameters["gamma"].interval is None and np.isfinite(r.values["gamma"])
    assert r.verdicts["gamma"]["verdict"] == "ambiguous"
    assert r.summary().startswith("run interrupted: interrupted in the intervals")
    with pytest.raises(ValueError, match="gamma has no interval: interrupted during the intervals"):
        r.confidence_interval("gamma")
