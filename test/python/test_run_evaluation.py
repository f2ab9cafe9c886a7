"""scripts/run_evaluation: the seed list, the spread over seeds and its goal lines; one short run on the
Nordland frames with a second seed (skipped without the data or the built localize_offline)."""

import contextlib
import csv
import io
import json
import os
import shutil
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import built_executable, fake_nordland, load

evaluation = load("run_evaluation")


def fake_metrics(within_one, recall=0.9):
    return {"within": {"0": within_one, "1": within_one, "2": within_one, "5": within_one},
            "recall_at_100_precision": recall, "average_precision": recall, "queries": 10}


class SeedListTest(unittest.TestCase):
    def test_ranges_and_lists(self):
        self.assertEqual(evaluation.parse_seeds("2-12"), list(range(2, 13)))
        self.assertEqual(evaluation.parse_seeds("2,5,7-9"), [2, 5, 7, 8, 9])
        self.assertEqual(evaluation.parse_seeds(" 5, 3-4,4 "), [3, 4, 5])  # sorted, each once
        self.assertEqual(evaluation.parse_seeds("none"), [])
        self.assertEqual(evaluation.parse_seeds(""), [])

    def test_bad_lists_are_refused(self):
        for text in ("3-1", "a", "2-", "1,,2", "-3"):
            with self.assertRaises(ValueError, msg=text):
                evaluation.parse_seeds(text)

    def test_label_joins_consecutive_seeds(self):
        self.assertEqual(evaluation.seed_label([1, 2, 3, 5, 7, 8]), "1-3, 5, 7-8")
        self.assertEqual(evaluation.seed_label([4]), "4")

    def test_command_line(self):
        args = evaluation.parse_args(["--seed", "3", "--extra-seeds", "1-4"])
        self.assertEqual(args.extra_seeds, [1, 2, 4])  # --seed is the main run's, not run twice
        self.assertEqual(evaluation.parse_args([]).extra_seeds, list(range(2, 13)))
        self.assertEqual(evaluation.parse_args(["--extra-seeds", "none"]).extra_seeds, [])
        with contextlib.redirect_stderr(io.StringIO()) as err, self.assertRaises(SystemExit):
            evaluation.parse_args(["--extra-seeds", "2-x"])
        self.assertIn("--extra-seeds", err.getvalue())
        # A fold count cross_validate cannot use was found only after the whole evaluation.
        for folds in ("1", "-2"):
            with contextlib.redirect_stderr(io.StringIO()) as err, self.assertRaises(SystemExit):
                evaluation.parse_args(["--folds", folds])
            self.assertIn("--folds must be 0 (off) or at least 2", err.getvalue())
        self.assertEqual(evaluation.parse_args(["--folds", "0"]).folds, 0)


class BadInputTest(unittest.TestCase):
    def test_a_seed_range_past_the_bound_is_refused_before_it_is_built(self):
        # 1-100000000 built a hundred million seeds and ran out of memory (a traceback).
        self.assertEqual(len(evaluation.parse_seeds("1-1000")), 1000)
        with self.assertRaises(ValueError) as caught:
            evaluation.parse_seeds("1-100000000")
        self.assertIn("more than 1000 seeds", str(caught.exception))
        with self.assertRaises(ValueError):
            evaluation.parse_seeds("1-600,2000-2600")

    def test_an_output_inside_the_data_folder_is_refused_before_anything_is_made_there(self):
        # make_nordland_scenarios refused it, but only after this run had made OUTPUT/{scenarios,runs,plots}
        # inside the data folder.
        tmp = tempfile.mkdtemp(prefix="test_run_evaluation_data_")
        try:
            fake_nordland(tmp)
            before = sorted(os.listdir(tmp))
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = evaluation.main(["--data", tmp, "--output", os.path.join(tmp, "out"), "--folds", "0",
                                        "--extra-seeds", "none", "--localize-offline", "/bin/true"])
            self.assertNotEqual(code, 0)
            self.assertIn("is inside the data folder", err.getvalue())
            self.assertEqual(sorted(os.listdir(tmp)), before)
        finally:
            shutil.rmtree(tmp)

    def test_a_setting_the_localizer_refuses_is_refused_before_the_output_is_touched(self):
        # Found at the first run, after the scenarios of an earlier evaluation in OUTPUT had been made again;
        # a candidate of the cross-validation only after the whole evaluation.
        binary = built_executable("localize_offline")
        if not binary:
            self.skipTest("localize_offline not built (source the catkin workspace)")
        tmp = tempfile.mkdtemp(prefix="test_run_evaluation_set_")
        try:
            data = fake_nordland(os.path.join(tmp, "data"), 12)  # listed only: the checks come first
            candidates = os.path.join(tmp, "candidates.txt")
            with open(candidates, "w") as f:
                f.write("defaults:\ntypo: max_stpe=3\n")
            typo = os.path.join(tmp, "typo.yaml")
            with open(typo, "w") as f:
                f.write("localizer:\n  max_stepp: 3\n")
            for options, reason in ((["--folds", "0", "--set", "max_step=0"], "parameter 'max_step' must be in 1 .. 16"),
                                    (["--folds", "0", "--params", typo],
                                     "unknown parameter 'max_stepp' refused (did you mean max_step?)"),
                                    (["--candidates", candidates], "candidate typo: "),
                                    (["--candidates", candidates], "unknown parameter 'max_stpe'"),
                                    (["--candidates", os.path.join(tmp, "none.txt")], "none.txt")):
                output = os.path.join(tmp, "out")
                os.makedirs(os.path.join(output, "scenarios"))
                with open(os.path.join(output, "results.md"), "w") as f:
                    f.write("an earlier evaluation\n")
                err = io.StringIO()
                with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                    code = evaluation.main(["--data", data, "--output", output, "--extra-seeds", "none",
                                            "--localize-offline", binary] + options)
                self.assertNotEqual(code, 0, options)
                self.assertIn(reason, err.getvalue())
                self.assertNotIn("Traceback", err.getvalue())
                self.assertEqual(sorted(os.listdir(output)), ["results.md", "scenarios"])
                self.assertEqual(os.listdir(os.path.join(output, "scenarios")), [])
                shutil.rmtree(output)
        finally:
            shutil.rmtree(tmp)

    def test_the_swapped_table_says_which_map_no_default_was_chosen_on(self):
        self.assertIn("winter map, summer query: the same places, a map the defaults were not chosen on",
                      evaluation.swapped_heading("winter", "summer"))
        self.assertIn("summer map, winter query: the roles the defaults were chosen in",
                      evaluation.swapped_heading("summer", "winter"))

    def test_frames_beyond_the_data_are_refused_before_any_folder_is_made(self):
        # make_nordland_scenarios refused --first 1700 --count 200 on fewer frames, but after run_evaluation
        # had made its output's empty folders.
        tmp = tempfile.mkdtemp(prefix="test_run_evaluation_range_")
        try:
            data = fake_nordland(os.path.join(tmp, "data"), 20)
            output = os.path.join(tmp, "out")
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = evaluation.main(["--data", data, "--output", output, "--first", "15", "--count", "10",
                                        "--extra-seeds", "none", "--localize-offline", "/bin/true"])
            self.assertEqual(code, 2, err.getvalue())
            self.assertIn("--first 15 --count 10 asks for frames up to 24; the data has 20 (frames 0-19)",
                          err.getvalue())
            self.assertFalse(os.path.exists(output))
        finally:
            shutil.rmtree(tmp)

    def test_a_run_that_stops_half_way_leaves_no_earlier_results_beside_its_runs(self):
        # An earlier run's results.md stayed beside the runs an interrupted run had rewritten, as if it were
        # theirs. Now it is renamed results.previous.md before anything is made. A localize_offline that takes
        # the settings and then fails stops this run at its first scenario.
        import numpy as np
        tmp = tempfile.mkdtemp(prefix="test_run_evaluation_stop_")
        try:
            data = fake_nordland(os.path.join(tmp, "data"), 12,
                                 lambda season, k: np.full((32, 64), 10 * k + (5 if season == "winter" else 0),
                                                           np.uint8))
            binary = os.path.join(tmp, "failing_localize_offline")
            with open(binary, "w") as f:
                f.write("#!/bin/sh\n[ \"$1\" = --check-params ] && exit 0\necho 'disk on fire' >&2\nexit 1\n")
            os.chmod(binary, 0o755)
            output = os.path.join(tmp, "out")
            os.makedirs(output)
            with open(os.path.join(output, "results.md"), "w") as f:
                f.write("an earlier evaluation\n")
            with open(os.path.join(output, "summary.png"), "w") as f:
                f.write("an earlier plot\n")
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = evaluation.main(["--data", data, "--output", output, "--extra-seeds", "none", "--folds", "0",
                                        "--scenarios", "aligned", "--methods", "dtw", "--localize-offline", binary])
            self.assertNotEqual(code, 0)
            self.assertIn("disk on fire", err.getvalue())
            self.assertFalse(os.path.exists(os.path.join(output, "results.md")))
            with open(os.path.join(output, "results.previous.md")) as f:
                self.assertEqual(f.read(), "an earlier evaluation\n")
            self.assertFalse(os.path.exists(os.path.join(output, "summary.png")))
            with open(os.path.join(output, "summary.previous.png")) as f:
                self.assertEqual(f.read(), "an earlier plot\n")
        finally:
            shutil.rmtree(tmp)


class ParameterSensitivityCommandTest(unittest.TestCase):
    """scripts/parameter_sensitivity runs run_evaluation once per setting: the command it builds must be
    one run_evaluation takes (with --set and no --folds 0 it refused every setting but the defaults)."""

    def test_each_setting_makes_a_command_run_evaluation_takes(self):
        import types
        sensitivity = load("parameter_sensitivity")
        commands = []

        def fake_run(command, **kwargs):
            commands.append(command)
            return types.SimpleNamespace(returncode=0, stdout="", stderr="")
        tmp = tempfile.mkdtemp(prefix="test_sensitivity_")
        try:
            os.makedirs(os.path.join(tmp, "runs"))
            with open(os.path.join(tmp, "runs", "aligned.dtw.json"), "w") as f:
                json.dump(fake_metrics(0.9), f)
            args = types.SimpleNamespace(data=None, localize_offline=None)
            real_run = sensitivity.subprocess.run
            sensitivity.subprocess.run = fake_run
            try:
                for setting in ("", "max_step=3", "max_step=3,ring_buffer_rows=20"):
                    sensitivity.evaluate(setting, 1, ["aligned"], args, tmp)
            finally:
                sensitivity.subprocess.run = real_run
        finally:
            shutil.rmtree(tmp)
        self.assertEqual(len(commands), 3)
        for command in commands:
            self.assertTrue(command[1].endswith("run_evaluation"), command)
            evaluation.parse_args(command[2:])  # exits (SystemExit) on a command it refuses


    def test_a_setting_it_would_fail_on_and_an_output_in_the_data_are_refused_before_any_run(self):
        # A typo in the last setting was found after every setting before it had run; an --output inside the data
        # folder was written there (run_evaluation and cross_validate refuse both).
        binary = built_executable("localize_offline")
        if not binary:
            self.skipTest("localize_offline not built (source the catkin workspace)")
        sensitivity = load("parameter_sensitivity")
        tmp = tempfile.mkdtemp(prefix="test_sensitivity_refusals_")
        try:
            data = fake_nordland(os.path.join(tmp, "data"))
            for options, words in ((["--set-list", ";max_step=3;max_shfit_px=6"],
                                    "--set-list: setting max_shfit_px=6: "),
                                   (["--set-list", ";max_step=3;max_shfit_px=6"], "did you mean max_shift_px?"),
                                   (["--set-list", "", "--output", os.path.join(data, "table.md")],
                                    "is inside the data folder %s" % data)):
                err = io.StringIO()
                with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()) as out:
                    code = sensitivity.main(["--data", data, "--localize-offline", binary] + options)
                self.assertEqual(code, 2, err.getvalue())
                self.assertIn(words, err.getvalue())
                self.assertEqual(out.getvalue(), "")  # no run, not even the table's header
            self.assertFalse(os.path.exists(os.path.join(data, "table.md")))
        finally:
            shutil.rmtree(tmp)


class SpreadTest(unittest.TestCase):
    def test_spread(self):
        spread = evaluation.seed_spread({3: 0.88, 1: 0.90, 2: 0.85}, 0.88)
        self.assertEqual(spread["seeds"], [1, 2, 3])
        self.assertEqual(spread["values"], [0.90, 0.85, 0.88])
        self.assertAlmostEqual(spread["mean"], 2.63 / 3)
        self.assertEqual((spread["min"], spread["max"]), (0.85, 0.90))
        self.assertEqual(spread["at_goal"], 2)  # 0.88 counts as at the goal
        self.assertIsNone(evaluation.seed_spread({1: 0.5})["at_goal"])

    def test_goal_on_the_mean_over_seeds(self):
        # seed 1 meets the stop-and-go goal (0.88), the mean of the three does not: (0.90 + 0.86 + 0.86) / 3
        runs = [("stop_and_go", "dtw", fake_metrics(0.90), {"wall_s": 1.0})]
        seed_runs = {("stop_and_go", "dtw"): {1: 0.90, 2: 0.86, 3: 0.86}}
        lines = evaluation.goal_lines(runs, seed_runs)
        self.assertEqual(lines[0], "- stop_and_go: within one frame 0.900, goal >= 0.88: met")
        self.assertEqual(lines[1], "- stop_and_go over seeds 1-3: within one frame mean 0.873 (0.860-0.900), "
                                   "goal >= 0.88: NOT met; 1 of 3 seeds at or above it")
        self.assertEqual(len(evaluation.goal_lines(runs)), 1)  # one seed: no spread line

    def test_table_row(self):
        table = evaluation.seed_table({("heading_offset", "dtw"): {1: 0.97, 2: 0.95},
                                       ("heading_offset", "seqslam"): {1: 0.86, 2: 0.84}})
        rows = table.splitlines()
        self.assertEqual(rows[2], "| heading_offset | dtw | 1-2 | 0.970 0.950 | 0.960 | 0.950 | 0.970 | 2 of 2 |")
        self.assertEqual(rows[3], "| heading_offset | seqslam | 1-2 | 0.860 0.840 | 0.850 | 0.840 | 0.860 | - |")


class NordlandRunTest(unittest.TestCase):
    """200 frames of the real data, stop-and-go with seeds 1 and 2: the spread table's value for seed 2 is
    the share of its queries within one frame, counted here from the files."""

    def setUp(self):
        self.data = evaluation.default_data_dir()
        if not os.path.isdir(os.path.join(self.data, "summer")):
            self.skipTest("Nordland data not found at %s" % self.data)
        self.binary = built_executable("localize_offline")
        if not self.binary:
            self.skipTest("localize_offline not built (source the catkin workspace)")
        self.out = tempfile.mkdtemp(prefix="test_run_evaluation_")

    def tearDown(self):
        shutil.rmtree(self.out)

    def test_second_seed(self):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
            code = evaluation.main(["--output", self.out, "--data", self.data, "--scenarios", "stop_and_go",
                                    "--methods", "dtw", "--first", "300", "--count", "200", "--extra-seeds", "2",
                                    "--localize-offline", self.binary])
        self.assertEqual(code, 0, err.getvalue())
        share = {}
        for seed, scenarios, runs in ((1, "scenarios", "runs"), (2, "scenarios/seed2", "runs/seed2")):
            with open(os.path.join(self.out, scenarios, "stop_and_go", "ground_truth.csv")) as f:
                truth = [int(row["keyframe"]) for row in csv.DictReader(f)]
            with open(os.path.join(self.out, runs, "stop_and_go.dtw.csv")) as f:
                answers = [int(row["keyframe"]) for row in csv.DictReader(f)]
            self.assertEqual(len(answers), len(truth))
            share[seed] = sum(1 for a, t in zip(answers, truth) if a >= 0 and abs(a - t) <= 1) / float(len(truth))
        with open(os.path.join(self.out, "runs", "seed2", "stop_and_go.dtw.json")) as f:
            self.assertAlmostEqual(json.load(f)["within"]["1"], share[2])
        with open(os.path.join(self.out, "results.md")) as f:
            text = f.read()
        self.assertIn("| stop_and_go | dtw | 1-2 | %.3f %.3f | %.3f |" % (share[1], share[2], (share[1] + share[2]) / 2),
                      text)
        self.assertIn("- stop_and_go over seeds 1-2: within one frame mean %.3f" % ((share[1] + share[2]) / 2), text)
        # the two seeds are two draws of the speed profile
        truths = []
        for scenarios in ("scenarios", "scenarios/seed2"):
            with open(os.path.join(self.out, scenarios, "stop_and_go", "ground_truth.csv")) as f:
                truths.append(f.read())
        self.assertNotEqual(truths[0], truths[1])

    def run_aligned(self, count, *options):
        """run_evaluation on aligned from frame 300 on; returns the Nordland file names in order."""
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
            code = evaluation.main(["--output", self.out, "--data", self.data, "--scenarios", "aligned",
                                    "--methods", "dtw", "--first", "300", "--count", str(count), "--extra-seeds",
                                    "none", "--localize-offline", self.binary] + list(options))
        self.assertEqual(code, 0, err.getvalue())
        return sorted(n for n in os.listdir(os.path.join(self.data, "winter")) if n.endswith(".png"))

    def test_the_cross_validated_table_comes_again_with_the_roles_swapped(self):
        names = self.run_aligned(40, "--folds", "2")
        for folder, map_season in (("cv", "summer"), ("cv_winter", "winter")):
            self.assertEqual(os.path.realpath(os.path.join(self.out, folder, "folds", "fold2", "aligned", "map",
                                                           "00000.png")),
                             os.path.realpath(os.path.join(self.data, map_season, names[298])))
        with open(os.path.join(self.out, "results.md")) as f:
            text = f.read()
        with open(os.path.join(self.out, "cv_winter", "cv.md")) as f:
            swapped = f.read().strip()
        self.assertIn("## Cross-validated, the roles swapped (winter map, summer query", text)
        self.assertIn(swapped, text)
        self.assertTrue(swapped.startswith("Map: the winter frames; query: the summer frames."), swapped[:80])
        self.assertFalse(evaluation.parse_args(["--no-swapped-roles"]).swapped_roles)

    def test_map_season_winter_maps_the_winter_frames_and_queries_the_summer_ones(self):
        names = self.run_aligned(60, "--map-season", "winter")
        for part, season in (("map", "winter"), ("query", "summer")):
            self.assertEqual(os.path.realpath(os.path.join(self.out, "scenarios", "aligned", part, "00000.png")),
                             os.path.realpath(os.path.join(self.data, season, names[300])))
        with open(os.path.join(self.out, "results.md")) as f:
            self.assertIn("(winter = map, summer = query)", f.read())

if __name__ == "__main__":
    unittest.main()
