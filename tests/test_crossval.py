"""danae_lite.research.crossval: splits never train on what they test; rows, spreads and paired differences
are the plain computations on the per-recording predictions."""
import numpy as np
import pandas as pd
import pytest

from danae_lite.research import crossval
from danae_lite.data import experiments, simulate
from danae_lite.evaluate import metrics
from danae_lite.research.leaderboard import run_leaderboard
from danae_lite.danae.train_types import TrainConfig

from conftest import network_items


@pytest.fixture(scope="module")
def motions():
    recs = {"handheld": [simulate.simulate("handheld", duration=8.0, seed=s, name=f"h{s}") for s in range(3)],
            "trolley": [simulate.simulate("handheld", duration=8.0, seed=10 + s, name=f"t{s}") for s in range(2)]}
    return recs


@pytest.fixture(scope="module")
def cv(motions):
    splits = crossval.leave_one_out(motions["handheld"], "handheld")
    splits.append(crossval.transfer(motions["handheld"], {"trolley": motions["trolley"]}, "handheld"))
    return crossval.run_splits(splits, name="oxiod", data="simulated", methods=("constant", "paper_kf", "danae"),
                               seeds=(0, 1), train_config=TrainConfig(max_steps=3, num_threads=1), progress=False)


def test_leave_one_out_holds_each_recording_out_once(motions):
    splits = crossval.leave_one_out(motions["handheld"], "handheld")
    assert [s.test[0].name for s in splits] == ["h0", "h1", "h2"]
    for s in splits:
        assert {r.name for r in s.train} == {"h0", "h1", "h2"} - {s.test[0].name}
    with pytest.raises(ValueError, match="at least 2"):
        crossval.leave_one_out(motions["handheld"][:1], "handheld")
    with pytest.raises(ValueError, match="both trained on and tested"):
        crossval.Split("bad", "in-motion", tuple(motions["handheld"]), tuple(motions["handheld"][:1]), {"h0": "x"})


def test_rows_cover_every_split_recording_method_and_angle(cv):
    r = cv.rows
    assert len(r) == (3 + 2) * 3 * 2 * 3  # held-out recordings x methods x subsets x angles
    assert set(r.protocol) == {"in-motion", "transfer"}
    assert set(r[r.protocol == "transfer"].group) == {"trolley"}
    assert r.seeds.max() == 2 and r[r.method == "constant"].seeds.max() == 1
    assert dict(zip(r.method, r.causal)) == {"constant": True, "paper_kf": True, "danae": False}


def test_a_row_is_the_leaderboard_of_its_split_on_that_recording(cv, motions):
    # the in-motion split holding out h1, recomputed with the leaderboard on that single split
    exp = experiments.Experiment("oxiod", "simulated", [motions["handheld"][0], motions["handheld"][2]],
                              [motions["handheld"][1]], "check")
    board = run_leaderboard(exp, methods=("paper_kf", "danae"), seeds=(0, 1),
                            train_config=TrainConfig(max_steps=3, num_threads=1), progress=False)
    for method in ("paper_kf", "danae"):
        ours = cv.rows[(cv.rows.test == "h1") & (cv.rows.method == method) & (cv.rows.samples == "all")]
        ref = board.table[(board.table.method == method) & (board.table.samples == "all")]
        for a in ("roll", "pitch", "yaw"):
            assert ours[ours.angle == a].rmse.iloc[0] == pytest.approx(ref[ref.angle == a].rmse.iloc[0], rel=1e-9)


def test_summary_is_mean_and_sample_std_over_recordings(cv):
    s = cv.summary("clean", "in-motion")
    per = cv.per_recording("pitch", "clean", "in-motion")
    assert s.loc["paper_kf", ("pitch", "mean")] == pytest.approx(per["paper_kf"].mean())
    assert s.loc["paper_kf", ("pitch", "std")] == pytest.approx(np.std(per["paper_kf"], ddof=1))
    assert s.loc["danae", "n"].item() == 3 and not s.loc["danae", "causal"].item()


def test_paired_differences(cv):
    p = cv.paired("danae", "paper_kf", "roll", "clean", "in-motion")
    assert len(p) == 3
    np.testing.assert_allclose(p["diff"], p["danae"] - p["paper_kf"])
    np.testing.assert_allclose(p["reduction_pct"], 100 * (1 - p["danae"] / p["paper_kf"]))
    assert p.attrs["wins"] == int((p["danae"] < p["paper_kf"]).sum())
    assert p.attrs["std_diff"] == pytest.approx(np.std(p["diff"], ddof=1))
    with pytest.raises(KeyError, match="vqf"):
        cv.paired("vqf", "paper_kf", "roll")


def test_write(cv, tmp_path):
    paths = cv.write(tmp_path)
    rows = pd.read_csv(paths["rows"])
    assert len(rows) == len(cv.rows)
    summary = pd.read_csv(paths["summary"])
    assert {"protocol", "group", "method", "roll_mean", "roll_std", "n"} <= set(summary.columns)


def test_spread_rule():
    assert metrics.spread([1.0, 3.0]) == (2.0, pytest.approx(np.sqrt(2.0)))
    m, s = metrics.spread([0.5])
    assert m == 0.5 and np.isnan(s)
    with pytest.raises(ValueError, match="NaN"):
        metrics.spread([1.0, np.nan])
    assert metrics.reduction_pct(0.5, 1.0) == 50.0 and metrics.reduction_pct(1.5, 1.0) == -50.0


def test_broad_split_scores_the_benchmark_metric_on_simulated_stand_ins(motions):
    split = crossval.broad_transfer(motions["handheld"], motions["trolley"])
    assert set(split.groups.values()) == {"disturbed"}  # simulated: no BROAD groups
    cv = crossval.run_splits([split], name="broad", data="simulated", aligned=True,
                             methods=("constant", "paper_kf"), progress=False)
    assert len(cv.trials) == 2 * 2 and set(cv.trials.method) == {"constant", "paper_kf"}
    s = cv.trial_summary()
    assert s.loc["paper_kf", "n"] == 2
    assert s.loc["paper_kf", "total_rmse_deg"] == pytest.approx(
        cv.trials[cv.trials.method == "paper_kf"].total_rmse_deg.mean())


@pytest.fixture(scope="module")
def cv_res(motions):
    splits = crossval.leave_one_out(motions["handheld"], "handheld")
    return crossval.run_splits(splits, name="oxiod", data="simulated",
                               methods=("paper_kf", "riann", "danae-res[paper_kf]", "danae-res[riann]"),
                               seeds=(0,), train_config=TrainConfig(max_steps=3, num_threads=1), progress=False)


def test_no_harm_pairs_each_correction_with_its_filter_recording_by_recording(cv_res, tmp_path):
    assert cv_res.corrections() == {"danae-res[paper_kf]": "paper_kf", "danae-res[riann]": "riann"}
    nh = cv_res.no_harm()
    assert list(nh.columns) == list(crossval.NO_HARM_COLUMNS)
    # 3 held-out recordings x 3 angles behind the paper's KF, x 2 behind RIANN (no yaw estimate)
    assert nh.groupby("filter").size().to_dict() == {"paper_kf": 9, "riann": 6}
    for source in ("paper_kf", "riann"):
        for a in ("roll", "pitch"):
            per = cv_res.per_recording(a)
            got = nh[(nh["filter"] == source) & (nh.quantity == f"{a} RMSE [rad]")].set_index("test")
            ref = per[[source, f"danae-res[{source}]"]].droplevel("group")
            np.testing.assert_allclose(got.filter_value, ref[source].loc[got.index])
            np.testing.assert_allclose(got.corrector_value, ref[f"danae-res[{source}]"].loc[got.index])
            np.testing.assert_allclose(got.change_pct, 100 * (1 - got.corrector_value / got.filter_value))
    s = cv_res.no_harm_summary()
    row = s.loc[("danae-res[paper_kf]", "paper_kf", "pitch RMSE [rad]")]
    sel = nh[(nh.corrector == "danae-res[paper_kf]") & (nh.quantity == "pitch RMSE [rad]")]
    assert row.recordings == 3 and row.worse_on == int((sel.change_pct < 0).sum())
    assert row.worst_change_pct == sel.change_pct.min()
    assert "no_harm" in cv_res.write(tmp_path)
    assert len(pd.read_csv(tmp_path / "no_harm.csv")) == len(nh)
    with pytest.raises(KeyError, match="vqf"):
        cv_res.no_harm({"danae-res[vqf]": "vqf"})


def test_no_harm_on_broad_trials_uses_the_benchmark_figures_in_degrees():
    keys = {"split": "s", "protocol": "transfer", "group": "tapping", "causal": True, "seeds": 1}
    rows = pd.DataFrame([{**keys, "test": t, "method": m, "samples": "clean", "angle": a, "rmse": v,
                          "mean_dev": 0.0, "max_dev": 0.0, "rmse_seed_std": np.nan, "n": 10}
                         for t in ("25", "26") for m, v in (("vqf", 0.02), ("danae-res[vqf]", 0.01))
                         for a in ("roll", "pitch", "yaw")])
    trials = pd.DataFrame([{**keys, "test": t, "method": m, "total_rmse_deg": tot, "heading_rmse_deg": tot,
                            "inclination_rmse_deg": 1.0}
                           for t, m, tot in (("25", "vqf", 2.0), ("25", "danae-res[vqf]", 3.0),
                                             ("26", "vqf", 4.0), ("26", "danae-res[vqf]", 3.0))])
    cv = crossval.CrossValidation("broad", "real", rows, trials, pd.DataFrame(), {"total": 0.0},
                                  methods=["vqf", "danae-res[vqf]"])
    nh = cv.no_harm().set_index(["test", "quantity"])
    assert nh.loc[("25", "total RMSE [deg]"), "change_pct"] == pytest.approx(-50.0)
    assert nh.loc[("26", "total RMSE [deg]"), "change_pct"] == pytest.approx(25.0)
    assert nh.loc[("25", "roll RMSE [rad]"), "change_pct"] == pytest.approx(50.0)
    s = cv.no_harm_summary().loc[("danae-res[vqf]", "vqf")]
    assert s.loc["total RMSE [deg]", "worse_on"] == 1 and s.loc["inclination RMSE [deg]", "worse_on"] == 0
    assert s.loc["total RMSE [deg]", "worst_change_pct"] == pytest.approx(-50.0)


def test_splits_in_workers_train_their_networks_together_first(cv_res, motions, tmp_path, monkeypatch):
    """jobs=2 with a cache: the networks of every split are trained in one pool first
    (crossval._pretrain), then the splits run in the workers and find them; the rows are
    those of one process without a cache, exactly (one torch thread everywhere)."""
    pooled = []
    pretrain = crossval.pretrain
    monkeypatch.setattr(crossval, "pretrain", lambda js, **kw: pooled.append(pretrain(js, **kw)) or pooled[-1])
    splits = crossval.leave_one_out(motions["handheld"], "handheld")
    cv2 = crossval.run_splits(splits, name="oxiod", data="simulated",
                              methods=("paper_kf", "riann", "danae-res[paper_kf]", "danae-res[riann]"),
                              seeds=(0,), train_config=TrainConfig(max_steps=3, num_threads=1), progress=False,
                              cache=tmp_path, jobs=2)
    # 3 splits x 2 denoisers x (1 prediction network + 2 inner-fold gate networks)
    assert pooled == [18] and len(network_items(tmp_path)) == 18
    pd.testing.assert_frame_equal(cv2.rows, cv_res.rows)


def test_combine_joins_runs_with_different_seeds_and_refuses_a_method_twice():
    import pandas as pd

    def part(methods, seeds, seconds):
        rows = pd.DataFrame([{c: None for c in crossval.ROW_COLUMNS} | {"method": m, "seeds": len(seeds)}
                             for m in methods], columns=list(crossval.ROW_COLUMNS))
        return crossval.CrossValidation(name="oxiod", data="real", rows=rows,
                                        trials=pd.DataFrame(columns=list(crossval.TRIAL_COLUMNS)),
                                        params=pd.DataFrame({"method": methods}), seconds=seconds,
                                        seeds=seeds, methods=list(methods))

    a = part(["vqf", "danae-res[vqf]"], (0, 1, 2), {"s1": 2.0, "total": 2.0})
    b = part(["fusion", "danae-res[fusion]"], (0,), {"s1": 1.5, "total": 1.5})
    c = crossval.combine([a, b])
    assert c.methods == ["vqf", "danae-res[vqf]", "fusion", "danae-res[fusion]"]
    assert c.seeds == (0, 1, 2) and c.seconds == {"s1": 3.5, "total": 3.5}
    assert c.rows.set_index("method").seeds.to_dict() == {"vqf": 3, "danae-res[vqf]": 3, "fusion": 1,
                                                          "danae-res[fusion]": 1}
    assert c.corrections() == {"danae-res[vqf]": "vqf", "danae-res[fusion]": "fusion"}
    with pytest.raises(ValueError, match="danae-res\\[vqf\\]"):
        crossval.combine([a, a])
    with pytest.raises(ValueError, match="different experiments"):
        crossval.combine([a, crossval.CrossValidation(**{**b.__dict__, "name": "broad"})])
