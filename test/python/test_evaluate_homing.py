"""scripts/evaluate_homing: figures and leave-one-place-out checked against hand-worked examples, the
synthetic pairs file, and (when the package is built and the Stromovka pairs are there) one real run."""

import contextlib
import csv
import io
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import built_executable, load

evaluate_homing = load("evaluate_homing")


def row(place, true, **estimates):
    out = {"place": place, "true_shift_px": str(true)}
    out.update({k: str(v) for k, v in estimates.items()})
    return out


class FiguresTest(unittest.TestCase):
    def test_four_pairs_by_hand(self):
        # (true, estimate): (2.0, 2.25) error 0.25, right sign; (-3.0, 1.5) error 4.5, wrong sign;
        # (0.5, -1.0) error 1.5, |true| < 1 px: not counted for the sign; (1.0, 0.0) error 1.0, an estimate
        # of 0 has the wrong sign. Errors sorted 0.25, 1.0, 1.5, 4.5: median 1.25, within 1 px 2 of 4,
        # right sign 1 of 3.
        rows = [row("1", 2.0, a=2.25), row("1", -3.0, a=1.5), row("1", 0.5, a=-1.0), row("1", 1.0, a=0.0)]
        median, within, sign = evaluate_homing.figures(rows, "a")
        self.assertAlmostEqual(median, 1.25)
        self.assertAlmostEqual(within, 0.5)
        self.assertAlmostEqual(sign, 1.0 / 3.0)

    def test_summary_is_mean_and_worst(self):
        mean, worst = evaluate_homing.summarize([(0.2, 0.9, 1.0), (0.6, 0.7, 0.9)])
        self.assertEqual(tuple(round(v, 9) for v in mean), (0.4, 0.8, 0.95))
        self.assertEqual(worst, (0.6, 0.7, 0.9))


class CrossValidateTest(unittest.TestCase):
    def test_each_place_is_scored_with_what_the_others_chose(self):
        # Column "good" is exact at places 1 and 2 and off by 3 px at place 3; "fair" is off by 0.5 px
        # everywhere. Held out place 3: chosen on 1 and 2 -> "good" (median 0), scored 3.0 on place 3.
        # Held out place 1: on 2 and 3, good's errors 0, 0, 3, 3 (median 1.5) against fair's 0.5 -> "fair".
        rows = []
        for place, good_error in (("1", 0.0), ("2", 0.0), ("3", 3.0)):
            for true in (2.0, -2.0):
                rows.append(row(place, true, good=true + good_error, fair=true + 0.5,
                                strip_sad=0, phase_correlation=0, phase_correlation_gray=0))
        result = {place: (chosen, held_out) for place, chosen, held_out, _ in
                  evaluate_homing.cross_validate(rows, ["good", "fair"])}
        self.assertEqual(result["3"][0], "good")
        self.assertAlmostEqual(result["3"][1][0], 3.0)
        self.assertEqual(result["1"][0], "fair")
        self.assertAlmostEqual(result["1"][1][0], 0.5)
        self.assertEqual(result["2"][0], "fair")

    def test_one_place_is_refused(self):
        with self.assertRaises(evaluate_homing.EvaluationError):
            evaluate_homing.cross_validate([row("1", 1.0, a=1.0)], ["a"])


class ResolutionScaleTest(unittest.TestCase):
    def test_grid_ranges_scale_and_the_rest_does_not(self):
        # 3 shifts x 5 vertical ranges x 4 shares x 2 fits x 2 costs = 240 specs at any scale; at scale 2
        # the first is 12 px x 2 = 24 with 0 rows, the last 20 x 2 = 40 px with 4 x 2 = 8 rows.
        once, twice = evaluate_homing.grid_specs(1), evaluate_homing.grid_specs(2)
        self.assertEqual(len(once), 240)
        self.assertEqual(len(twice), 240)
        self.assertEqual(once[0], "12:0:0.5:parabola")
        self.assertEqual(twice[0], "24:0:0.5:parabola")
        self.assertEqual(twice[-1], "40:8:1:equiangular:robust")
        self.assertIn("32:4:1:equiangular:robust", twice)  # the default (16 px, 2 rows) at 128 px

    def test_errors_in_px_of_the_64_px_image(self):
        # At 256 px (scale 4) a true shift of 10 px is 2.5 px of the 64-px image; an estimate of 11 px
        # (error 1 px at 256) is 2.75 (error 0.25); -6 px against a true -4: error 0.5 at 64 px.
        rows = evaluate_homing.to_64px([row("1", 10.0, a=11.0), row("1", -4.0, a=-6.0)], 4)
        self.assertEqual(rows[0]["place"], "1")
        self.assertAlmostEqual(float(rows[0]["true_shift_px"]), 2.5)
        self.assertAlmostEqual(float(rows[0]["a"]), 2.75)
        # errors 0.25 and 0.5: median 0.375, both within 1 px; |true| 2.5 and 1.0 >= 1 px, both right
        self.assertEqual(tuple(round(v, 9) for v in evaluate_homing.figures(rows, "a")), (0.375, 1.0, 1.0))

    def test_a_scale_below_one_is_refused(self):
        with contextlib.redirect_stderr(io.StringIO()) as err:
            with self.assertRaises(SystemExit) as caught:
                evaluate_homing.main(["--resolution-scale", "0"])
        self.assertEqual(caught.exception.code, 2)
        self.assertIn("--resolution-scale must be a positive integer", err.getvalue())


class SyntheticPairsTest(unittest.TestCase):
    def test_repeat_frames_against_their_teach_frames(self):
        with tempfile.TemporaryDirectory() as tmp:
            os.makedirs(os.path.join(tmp, "teach_images"))
            os.makedirs(os.path.join(tmp, "repeat_images"))
            with open(os.path.join(tmp, "ground_truth.csv"), "w") as f:
                f.write("query_index,teach_frame,heading_offset_rad,expected_shift_px_64,horizontal_fov_rad,"
                        "mean_shift_px_64,route_position_m,segment\n"
                        "0,0,0.000000,0.0000,1.570796,0.0000,0.0,normal\n"
                        "1,3,0.087266,2.7997,1.570796,3.6740,1.5,normal\n")
            out = os.path.join(tmp, "pairs.csv")
            evaluate_homing.synthetic_pairs(tmp, out)
            with open(out) as f:
                pairs = list(csv.DictReader(f))
        self.assertEqual(len(pairs), 2)
        self.assertTrue(pairs[1]["map_image"].endswith(os.path.join("teach_images", "00003.png")))
        self.assertTrue(pairs[1]["query_image"].endswith(os.path.join("repeat_images", "00001.png")))
        self.assertEqual(pairs[1]["true_shift_px"], "3.6740")  # the whole-width mean shift

    def test_missing_folder_is_a_clear_error(self):
        with tempfile.TemporaryDirectory() as tmp:
            with self.assertRaises(evaluate_homing.EvaluationError) as caught:
                evaluate_homing.synthetic_pairs(tmp, os.path.join(tmp, "pairs.csv"))
        self.assertIn("generate_route --images", str(caught.exception))


class OutputTest(unittest.TestCase):
    def test_the_estimates_are_not_written_over_the_pairs_they_read(self):
        # --csv equal to --pairs rewrote the pairs with the estimates; the next run scored against those.
        with tempfile.TemporaryDirectory() as tmp:
            pairs = os.path.join(tmp, "pairs.csv")
            text = "place,map_image,query_image,true_shift_px\n1,images/a.png,images/b.png,4.0\n"
            with open(pairs, "w") as f:
                f.write(text)
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                code = evaluate_homing.main(["--pairs", pairs, "--csv", pairs, "--tool", "/bin/true"])
            self.assertEqual(code, 1)
            self.assertIn("--csv %s is the pairs file it reads" % pairs, err.getvalue())
            with open(pairs) as f:
                self.assertEqual(f.read(), text)

    def test_bad_options_are_refused_by_name_before_the_run(self):
        # --true-width 0 was refused by homing_pairs with its usage, naming nothing; --csv in a missing
        # folder was a traceback after the run.
        with tempfile.TemporaryDirectory() as tmp:
            for argv, words in ((["--true-width", "0"], "--true-width must be a positive width in px, got 0.0"),
                                (["--true-width", "nan"], "--true-width must be a positive width in px, got nan"),
                                (["--csv", os.path.join(tmp, "nodir", "x.csv")], "its folder does not exist")):
                err = io.StringIO()
                with contextlib.redirect_stderr(err), self.assertRaises(SystemExit) as raised:
                    evaluate_homing.main(argv + ["--tool", "/bin/true"])
                self.assertEqual(raised.exception.code, 2, argv)
                self.assertIn(words, err.getvalue())


class HomingPairsArgumentsTest(unittest.TestCase):
    def test_numbers_are_read_whole_or_refused_by_name(self):
        # atoi / atof took 'abc' as 0 (a column of zeros, exit 0) and '12abc' as 12; --true-width 0 printed the
        # usage without a reason. Arguments are read before the pairs file, so none is needed here.
        tool = built_executable("homing_pairs")
        if tool is None:
            self.skipTest("needs the built homing_pairs (source devel/setup.bash)")
        for argv, words in ((["--homing", "abc:0:0.5"], "--homing takes M:V:S[:parabola|equiangular[:robust]] (M and V "
                             "integers, S a number), got abc:0:0.5"),
                            (["--homing", "16:2.5:1"], "got 16:2.5:1"),
                            (["--homing", "16:2:x"], "got 16:2:x"),
                            (["--true-width", "12abc"], "--true-width takes the width in px of the images the true "
                             "shifts are measured on (> 0), got '12abc'"),
                            (["--true-width", "0"], "got '0'"),
                            (["--true-width", "nan"], "got 'nan'")):
            done = subprocess.run([tool, "--pairs", "/nonexistent/pairs.csv"] + argv, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, universal_newlines=True, timeout=30)
            self.assertEqual(done.returncode, 2, argv)
            self.assertIn(words, done.stderr)


class RealPairsTest(unittest.TestCase):
    def test_default_run_on_stromovka(self):
        tool = built_executable("homing_pairs")
        pairs = evaluate_homing.default_pairs()
        if tool is None or not os.path.isfile(pairs):
            self.skipTest("needs the built homing_pairs (source devel/setup.bash) and %s" % pairs)
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            self.assertEqual(evaluate_homing.main(["--tool", tool]), 0)
        lines = out.getvalue().splitlines()
        self.assertTrue(lines[0].startswith("660 pairs from 5 place(s) (582 with |true shift| >= 1 px)"), lines[0])
        package = next(line for line in lines if "(package)" in line)
        phase = next(line for line in lines if line.strip().startswith("phase_correlation "))
        median = float(package.split("median")[1].split("px")[0])
        self.assertLess(median, float(phase.split("median")[1].split("px")[0]))

    def test_twice_the_resolution_reports_px_of_the_64_px_image(self):
        # --resolution-scale 2: preprocessed at 128x64, the default search doubled (32 px, 4 rows), and the
        # true shifts written to --csv are those of the 64-px image (1024-px shift x 64 / 1024), not 128's.
        tool = built_executable("homing_pairs")
        pairs = evaluate_homing.default_pairs()
        if tool is None or not os.path.isfile(pairs):
            self.skipTest("needs the built homing_pairs (source devel/setup.bash) and %s" % pairs)
        with open(pairs) as f:
            truth = {(r["map_image"], r["query_image"]): float(r["true_shift_px"]) * 64.0 / 1024.0
                     for r in csv.DictReader(f)}
        with tempfile.TemporaryDirectory() as tmp:
            out_csv = os.path.join(tmp, "rows.csv")
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                self.assertEqual(evaluate_homing.main(["--tool", tool, "--resolution-scale", "2", "--csv", out_csv]), 0)
            with open(out_csv) as f:
                rows = list(csv.DictReader(f))
        self.assertIn("Preprocessed at 128x64 px", out.getvalue())
        self.assertIn("homing_32_4_1_equiangular_robust (package)", out.getvalue())
        self.assertEqual(len(rows), 660)
        for r in rows:
            self.assertAlmostEqual(float(r["true_shift_px"]), truth[(r["map_image"], r["query_image"])], places=3)

    def test_robust_column_is_measured_and_a_bad_spec_refused(self):
        # homing_pairs --homing M:V:S:FIT:robust adds a column named homing_M_V_S_FIT_robust; anything else
        # in the fifth field is refused with the expected form, before any image is read.
        tool = built_executable("homing_pairs")
        pairs = evaluate_homing.default_pairs()
        if tool is None or not os.path.isfile(pairs):
            self.skipTest("needs the built homing_pairs (source devel/setup.bash) and %s" % pairs)
        rows = evaluate_homing.run_tool(tool, pairs, 1024.0, ["16:2:1:equiangular", "16:2:1:equiangular:robust"], [])
        self.assertEqual(len(rows), 660)
        self.assertIn("homing_16_2_1_equiangular_robust", rows[0])
        # the flag reaches the estimator: the robust costs move the subpixel shift of most pairs
        differing = sum(1 for r in rows if r["homing_16_2_1_equiangular"] != r["homing_16_2_1_equiangular_robust"])
        self.assertGreater(differing, 330, "robust and plain agree on %d of 660 pairs" % (660 - differing))
        with self.assertRaises(evaluate_homing.EvaluationError) as caught:
            evaluate_homing.run_tool(tool, pairs, 1024.0, ["16:2:1:equiangular:huber"], [])
        self.assertIn("M:V:S[:parabola|equiangular[:robust]]", str(caught.exception))


if __name__ == "__main__":
    unittest.main()
