"""scripts/cross_validate and the scenarios and calibration it rests on: hand-worked examples."""

import os
import re
import subprocess
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import built_executable, fake_nordland, load

cross_validate = load("cross_validate")
scenarios = load("make_nordland_scenarios")
evaluate = load("evaluate")


class FoldScenarioTest(unittest.TestCase):
    def test_kidnapped_visits_the_thirds_in_the_order_first_last_middle(self):
        map_frames, query, keyframes, shifts = scenarios.kidnapped(9)
        self.assertEqual(map_frames, list(range(9)))
        self.assertEqual(query, [0, 1, 2, 6, 7, 8, 3, 4, 5])
        self.assertEqual(keyframes, query)
        self.assertEqual(shifts, [0] * 9)

    def test_mid_start_starts_a_third_of_the_way_along(self):
        map_frames, query, keyframes, _ = scenarios.mid_start(10)
        self.assertEqual(map_frames, list(range(10)))
        self.assertEqual(query, [3, 4, 5, 6, 7, 8, 9])
        self.assertEqual(keyframes, query)

    def test_fog_stretches_are_20_to_60_frames_with_30_to_80_clear_between(self):
        fog = scenarios.fog_stretches(2000, np.random.default_rng(3))
        runs, value, length = [], fog[0], 0
        for f in fog:
            if f == value:
                length += 1
            else:
                runs.append((value, length))
                value, length = f, 1
        runs.append((value, length))
        self.assertEqual(runs[0][0], 0)
        self.assertTrue(20 <= runs[0][1] <= 60)
        for v, n in runs[1:-1]:
            self.assertTrue((20 <= n <= 60) if v else (30 <= n <= 80), (v, n))

    def test_fogged_keeps_a_fifth_of_the_contrast_around_the_mean(self):
        image = np.array([[100, 200], [100, 200]], np.uint8)  # mean 150, deviations -50 / +50
        out = scenarios.fogged(image, seed=1).astype(float)
        # 150 + 0.2 * (+-50) = 160 / 140, plus noise of std 3 gray levels
        self.assertTrue(np.all(np.abs(out[:, 1] - 160) <= 15))
        self.assertTrue(np.all(np.abs(out[:, 0] - 140) <= 15))


class CalibrationTest(unittest.TestCase):
    def test_reliability_and_expected_calibration_error_by_hand(self):
        # bin [0.1, 0.2): confidences 0.1, 0.1, correct 1 of 2 -> |0.5 - 0.1| = 0.4, weight 2/4
        # bin [0.9, 1.0]: confidences 0.9, 1.0, correct 2 of 2 -> |1 - 0.95| = 0.05, weight 2/4
        # ECE = 0.5 * 0.4 + 0.5 * 0.05 = 0.225
        r = evaluate.reliability([0.1, 0.1, 0.9, 1.0], [True, False, True, True])
        self.assertAlmostEqual(r["expected_calibration_error"], 0.225)
        self.assertEqual([b["count"] for b in r["bins"]], [2, 2])
        self.assertAlmostEqual(r["bins"][1]["mean_confidence"], 0.95)

    def test_longest_run(self):
        self.assertEqual(evaluate.longest_run([False, True, True, False, True, True, True]), 3)
        self.assertEqual(evaluate.longest_run([]), 0)

    def test_platt_fit_recovers_a_logistic_law(self):
        # correct with probability sigma(-1 + 6 c): a large sample drawn from it gives back about -1 and 6
        rng = np.random.default_rng(5)
        c = rng.uniform(0, 1, 20000)
        correct = rng.uniform(0, 1, c.size) < 1.0 / (1.0 + np.exp(-(-1.0 + 6.0 * c)))
        offset, slope = cross_validate.fit_calibration(c, correct)
        self.assertAlmostEqual(offset, -1.0, delta=0.1)
        self.assertAlmostEqual(slope, 6.0, delta=0.3)

    def test_within_one_on_frames_neither_dark_nor_stationary(self):
        # 4 queries: 0 right, 1 wrong and dark, 2 wrong and stationary, 3 wrong: 1 of 4 within one overall;
        # of the 2 frames neither dark nor stationary (0 and 3), 1
        truth = {q: {"keyframe": q, "exact": None, "shift": None, "heading": None, "dark": q == 1,
                     "stationary": q == 2} for q in range(4)}
        results = {"query_index": [0, 1, 2, 3], "keyframe": [0, 9, 9, 9], "confidence": [0.5] * 4,
                   "shift_px": [0.0] * 4, "homing_angle_rad": [0.0] * 4,
                   "status": ["tracking"] * 4}
        figures = cross_validate.figures_of(evaluate.evaluate(results, truth))
        self.assertAlmostEqual(figures["within_one"], 0.25)
        self.assertAlmostEqual(figures["within_one_observable"], 0.5)
        self.assertIsNone(figures["within_one_reference"])  # no keyframe_stationary column

    def test_the_reference_from_the_ground_truth_is_a_figure_of_the_fold(self):
        # truth 0 1 2 2 2 2; the teach camera stood at keyframe 2 (queries 2-5 blind). From query 1 at speed 1:
        # 2, 3, 4, 5 against 2, 2, 2, 2 -> queries 2 and 3 right: 4 of 6, whatever the answers were
        truth = {q: {"keyframe": min(q, 2), "exact": None, "shift": None, "heading": None, "dark": False,
                     "stationary": q >= 2, "keyframe_stationary": q >= 2} for q in range(6)}
        results = {"query_index": list(range(6)), "keyframe": [9] * 6, "confidence": [0.5] * 6,
                   "shift_px": [0.0] * 6, "homing_angle_rad": [0.0] * 6, "status": ["tracking"] * 6}
        figures = cross_validate.figures_of(evaluate.evaluate(results, truth))
        self.assertAlmostEqual(figures["within_one"], 0.0)
        self.assertAlmostEqual(figures["within_one_reference"], 4 / 6)
        self.assertAlmostEqual(figures["within_one_or_copy"], 0.0)  # 9 is no keyframe the teach camera stood at
        # truth 0-5, the teach camera standing at keyframes 2-5 (each row names its keyframe standing); answers
        # 0 1 2 3 2 2: queries 4 and 5 are 2 and 3 off, wrong, but at keyframe 2 of the same standing run
        truth = {q: {"keyframe": q, "exact": None, "shift": None, "heading": None, "dark": False,
                     "stationary": q >= 2, "keyframe_stationary": q >= 2} for q in range(6)}
        results["keyframe"] = [0, 1, 2, 3, 2, 2]
        figures = cross_validate.figures_of(evaluate.evaluate(results, truth))
        self.assertAlmostEqual(figures["within_one"], 4 / 6)
        self.assertAlmostEqual(figures["within_one_or_copy"], 1.0)

    def test_the_threshold_a_robot_could_ship_is_set_on_the_other_folds(self):
        # Folds 0 and 1 train, fold 2 is held out; one scenario, one run each, calibration off (slope 0).
        # Wrong answers on the training folds: 0.6 (fold 0) and 0.7 (fold 1, answered); fold 1's 0.95 is not
        # answered and fold 0's 0.9 is lost (published 0): neither counts. Threshold 0.7.
        def figures(confidence, correct, lost, answered):
            return {"aligned": {"_confidence": [np.array(confidence)], "_correct": [np.array(correct)],
                                "_lost": [np.array(lost)], "_answered": [np.array(answered)]}}
        table = {"a": {0: figures([0.8, 0.6, 0.9], [True, False, False], [False, False, True], [True] * 3),
                       1: figures([0.7, 0.95, 0.99], [False, False, True], [False] * 3, [True, False, True]),
                       # held out: 0.75 and 0.9 right and accepted, 0.72 wrong and accepted, 0.7 right but not
                       # above the threshold, one query unanswered
                       2: figures([0.75, 0.9, 0.72, 0.7, 0.99], [True, True, False, True, True], [False] * 5,
                                  [True, True, True, True, False])}}
        shipped, threshold = cross_validate.threshold_figures(table, "a", [0, 1, 2], 2, 0.0, 0.0)
        self.assertAlmostEqual(threshold, 0.7)
        self.assertAlmostEqual(shipped["aligned"][0], 2 / 5)
        self.assertEqual(shipped["aligned"][1], 1)
        # No wrong answer to train on: every answer is accepted.
        self.assertEqual(cross_validate.threshold_without_wrong([0.5], [True], [True]), -1.0)

    def test_lost_answers_publish_zero(self):
        p = cross_validate.calibrated([0.0, 0.5], [False, True], -1.0, 4.0)
        self.assertAlmostEqual(p[0], 1.0 / (1.0 + np.exp(1.0)))
        self.assertEqual(p[1], 0.0)


class SelectionTest(unittest.TestCase):
    def test_each_fold_is_chosen_on_the_others(self):
        # a is best on folds 0 and 1, b on fold 2; held out fold 2, a wins on folds 0-1 (0.9 vs 0.5);
        # held out fold 0, folds 1-2 give a 0.55 and b 0.7: b
        scores = {"a": {0: 0.9, 1: 0.9, 2: 0.2}, "b": {0: 0.5, 1: 0.5, 2: 0.9}}
        self.assertEqual(cross_validate.choose(scores, [0, 1, 2], 2)[0], "a")
        self.assertEqual(cross_validate.choose(scores, [0, 1, 2], 0)[0], "b")
        self.assertAlmostEqual(cross_validate.choose(scores, [0, 1, 2], 0)[1], 0.7)

    def test_choice_by_recall_takes_the_candidate_whose_confidence_ranks_best(self):
        # two candidates with the same answers (within one equal), confidences that rank them differently:
        # by within one the first in order wins the tie on every fold; by recall b (mean 0.8 on any two
        # folds against a's 0.5) is chosen for each held-out fold
        def figures(within_one, recall):
            return {s: {"within_one": within_one, "recall": recall} for s in cross_validate.REPORTED}
        table = {"a": {f: figures(0.9, 0.5) for f in range(3)}, "b": {f: figures(0.9, 0.8) for f in range(3)}}
        self.assertAlmostEqual(cross_validate.fold_score(table["b"][0], "recall"), 0.8)
        self.assertAlmostEqual(cross_validate.fold_score(table["b"][0]), 0.9)
        for by, expected in (("within_one", "a"), ("recall", "b")):
            scores = cross_validate.fold_scores(table, [0, 1, 2], by)
            for held_out in range(3):
                self.assertEqual(cross_validate.choose(scores, [0, 1, 2], held_out)[0], expected, by)
        self.assertEqual(cross_validate.parse_args(["--choose-by", "recall"]).choose_by, "recall")
        self.assertEqual(cross_validate.parse_args([]).choose_by, "within_one")

    def test_candidates_file(self):
        candidates = cross_validate.parse_candidates("# comment\nfast: max_step=3 ring_buffer_rows=20\n\nslow: max_step=1\n")
        self.assertEqual(candidates, [("defaults", []), ("fast", ["max_step=3", "ring_buffer_rows=20"]),
                                      ("slow", ["max_step=1"])])
        with self.assertRaises(ValueError):
            cross_validate.parse_candidates("fast max_step=3\n")
        with self.assertRaises(ValueError):
            cross_validate.parse_candidates("a: x=1\na: y=2\n")
        with self.assertRaises(ValueError):
            cross_validate.parse_candidates("a: novalue\n")

    @unittest.skipIf(built_executable("localize_offline") is None, "localize_offline not built (source the workspace)")
    def test_the_shipped_candidate_grids_name_parameters_in_range(self):
        # doc/cv_core_parameters.txt, doc/cv_decision_parameters.txt, doc/cv_ablations.txt, doc/cv_posterior.txt
        # and doc/cv_all_switches.txt (the first three's union and four rules' switches), the grids
        # doc/results.md reports:
        # every name one localize_offline takes, every value inside its range (a misspelt name or a value out
        # of range would be refused or corrected by the runs, and the figures would be those of another grid).
        help_text = subprocess.run([built_executable("localize_offline"), "--help-advanced"], stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, universal_newlines=True).stdout
        ranges = {m.group(1): (float(m.group(2)), float(m.group(3))) for m in
                  re.finditer(r"^    ([a-z_]+) = \S+  \(([-0-9.e]+) \.\. ([-0-9.e]+)", help_text, re.M)}
        switches = set(re.findall(r"^    ([a-z_]+) = \S+  \(true \| false\)", help_text, re.M))
        self.assertIn("filter_window", ranges)
        self.assertIn("column_centering", switches)
        doc = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "doc")
        for file_name, count in (("cv_core_parameters.txt", 18), ("cv_decision_parameters.txt", 19),
                                 ("cv_ablations.txt", 19), ("cv_posterior.txt", 26),
                                 ("cv_all_switches.txt", 18 + 17 + 18 + 4 + 1)):
            with open(os.path.join(doc, file_name)) as f:
                candidates = cross_validate.parse_candidates(f.read())
            self.assertEqual(len(candidates), count, file_name)
            for name, assignments in candidates[1:]:
                for assignment in assignments:
                    key, value = assignment.split("=", 1)
                    if value in ("true", "false"):
                        self.assertTrue(key in switches, "%s, %s: %s is not a switch" % (file_name, name, key))
                        continue
                    self.assertTrue(key in ranges, "%s, %s: %s is not a parameter" % (file_name, name, key))
                    self.assertTrue(ranges[key][0] <= float(value) <= ranges[key][1],
                                    "%s, %s: %s is out of range" % (file_name, name, assignment))


class BadInputTest(unittest.TestCase):
    """Errors that were tracebacks, or came after folders were made inside the data."""

    def run_main(self, *args):
        import contextlib
        import io
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = cross_validate.main(list(args))
        return code, err.getvalue()

    def test_an_output_inside_the_data_folder_is_refused_before_anything_is_made_there(self):
        import shutil
        import tempfile
        tmp = tempfile.mkdtemp(prefix="test_cross_validate_data_")
        try:
            fake_nordland(tmp)
            code, err = self.run_main("--data", tmp, "--output", os.path.join(tmp, "cv"), "--folds", "2",
                                      "--fold-size", "30", "--localize-offline", "/bin/true")
            self.assertEqual(code, 1)
            self.assertIn("is inside the data folder", err)
            self.assertEqual(sorted(os.listdir(tmp)), ["summer", "winter"])
        finally:
            shutil.rmtree(tmp)

    def test_a_runner_that_writes_no_results_is_an_error_not_a_traceback(self):
        # --localize-offline /bin/true exits 0 and writes nothing: evaluate's InputError was a traceback.
        import shutil
        import tempfile
        nordland = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..",
                                                 "shared", "data", "nordland"))
        if not os.path.isdir(os.path.join(nordland, "summer")):
            self.skipTest("needs the Nordland frames in %s" % nordland)
        tmp = tempfile.mkdtemp(prefix="test_cross_validate_runner_")
        try:
            data = os.path.join(tmp, "data")
            for season in ("summer", "winter"):
                os.makedirs(os.path.join(data, season))
                for name in sorted(os.listdir(os.path.join(nordland, season)))[:60]:
                    os.symlink(os.path.join(nordland, season, name), os.path.join(data, season, name))
            code, err = self.run_main("--data", data, "--output", os.path.join(tmp, "cv"), "--folds", "2",
                                      "--fold-size", "30", "--seeds", "1", "--localize-offline", "/bin/true")
            self.assertEqual(code, 1)
            self.assertTrue(err.startswith("cross_validate: error: "), err)
            self.assertNotIn("Traceback", err)
        finally:
            shutil.rmtree(tmp)

    def test_a_candidate_the_localizer_refuses_is_named_before_any_fold_is_made(self):
        import shutil
        import tempfile
        binary = built_executable("localize_offline")
        if not binary:
            self.skipTest("localize_offline not built (source the catkin workspace)")
        tmp = tempfile.mkdtemp(prefix="test_cross_validate_candidate_")
        try:
            data = fake_nordland(os.path.join(tmp, "data"), 60)
            candidates = os.path.join(tmp, "candidates.txt")
            with open(candidates, "w") as f:
                f.write("defaults:\nsteep: max_step=3\ntypo: max_stpe=3\n")
            code, err = self.run_main("--data", data, "--output", os.path.join(tmp, "cv"), "--folds", "2",
                                      "--fold-size", "30", "--candidates", candidates, "--localize-offline", binary)
            self.assertEqual(code, 1)
            self.assertIn("candidate typo: ", err)
            self.assertIn("unknown parameter 'max_stpe'", err)
            self.assertFalse(os.path.exists(os.path.join(tmp, "cv")), "nothing made before the check")
            # A candidates file that is not there: named, not a raw "[Errno 2] ...: 'nope.txt'".
            missing = os.path.join(tmp, "nope.txt")
            code, err = self.run_main("--data", data, "--output", os.path.join(tmp, "cv"), "--folds", "2",
                                      "--fold-size", "30", "--candidates", missing, "--localize-offline", binary)
            self.assertEqual(code, 1)
            self.assertIn("cross_validate: error: --candidates %s: No such file or directory" % missing, err)
        finally:
            shutil.rmtree(tmp)

    def test_a_run_that_stops_half_way_leaves_no_earlier_tables_beside_its_runs(self):
        # An earlier run's cv.md stayed beside the runs of one that stopped half way, as if it were theirs.
        import tempfile
        earlier = tempfile.mkdtemp(prefix="test_cross_validate_earlier_")
        self.addCleanup(__import__("shutil").rmtree, earlier)
        output = os.path.join(earlier, "cv")
        os.makedirs(output)
        with open(os.path.join(output, "cv.md"), "w") as f:
            f.write("an earlier table\n")
        _, _, code, err = self.folds_made(60, "--output", output)  # the runner writes nothing: it stops
        self.assertEqual(code, 1, err)
        self.assertFalse(os.path.exists(os.path.join(output, "cv.md")))
        with open(os.path.join(output, "cv.previous.md")) as f:
            self.assertEqual(f.read(), "an earlier table\n")

    def folds_made(self, frames, *args):
        """Fake Nordland frames (summer frame k all k, winter 100 + k), then cross_validate with 2 folds of 30 and
        a runner that writes no results (/bin/true): it stops at the first evaluation, after the folds are made.
        Returns (the data folder, the output folder, exit code, stderr)."""
        import shutil
        import tempfile
        import numpy as np
        tmp = tempfile.mkdtemp(prefix="test_cross_validate_folds_")
        self.addCleanup(shutil.rmtree, tmp)
        data = fake_nordland(os.path.join(tmp, "data"), frames,
                             lambda season, k: np.full((4, 8), (season == "winter") * 100 + k, np.uint8))
        output = os.path.join(tmp, "cv")
        code, err = self.run_main("--data", data, "--output", output, "--folds", "2", "--fold-size", "30",
                                  "--seeds", "1", "--localize-offline", "/bin/true", *args)
        return data, output, code, err

    def test_map_season_winter_makes_folds_with_the_winter_frames_as_the_map(self):
        data, output, code, err = self.folds_made(60, "--map-season", "winter")
        self.assertEqual(code, 1, err)
        fold2 = os.path.join(output, "folds", "fold2")
        for scenario in ("aligned", os.path.join("seed1", "stop_and_go")):
            self.assertEqual(os.path.realpath(os.path.join(fold2, scenario, "map", "00000.png")),
                             os.path.realpath(os.path.join(data, "winter", "images-00030.png")))
        self.assertEqual(os.path.realpath(os.path.join(fold2, "aligned", "query", "00000.png")),
                         os.path.realpath(os.path.join(data, "summer", "images-00030.png")))

    def test_first_frame_moves_every_fold_and_is_checked_against_the_line(self):
        # 2 folds of 30 from frame 15: frames 15-44 and 45-74
        data, output, code, err = self.folds_made(80, "--first-frame", "15")
        self.assertEqual(code, 1, err)
        for fold, first in (("fold1", 15), ("fold2", 45)):
            self.assertEqual(os.path.realpath(os.path.join(output, "folds", fold, "aligned", "map", "00000.png")),
                             os.path.realpath(os.path.join(data, "summer", "images-%05d.png" % first)))
        # from frame 25 they would need frame 84 of 80: refused before anything is made
        data, output, code, err = self.folds_made(80, "--first-frame", "25")
        self.assertEqual(code, 1)
        self.assertIn("from frame 25 need 85 frames", err)
        self.assertFalse(os.path.exists(output))

if __name__ == "__main__":
    unittest.main()
