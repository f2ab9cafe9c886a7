"""scripts/evaluate: metrics checked against hand-worked examples."""

import contextlib
import io
import json
import os
import shutil
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import load

evaluate = load("evaluate")


def write(path, text):
    with open(path, "w") as f:
        f.write(text)


class PrecisionRecallTest(unittest.TestCase):
    def test_five_ranked_queries(self):
        # ranked by confidence: hit, hit, miss, hit, miss
        # precision 1/1, 2/2, 2/3, 3/4, 3/5; recall 1/5, 2/5, 2/5, 3/5, 3/5
        # AP = 0.2*1 + 0.2*1 + 0*(2/3) + 0.2*(3/4) + 0*(3/5) = 0.55; recall at 100% precision = 0.4
        confidence = [0.6, 0.9, 0.5, 0.8, 0.7]
        correct = [True, True, False, True, False]
        thresholds, precision, recall = evaluate.precision_recall(confidence, correct, [True] * 5)
        np.testing.assert_allclose(thresholds, [0.9, 0.8, 0.7, 0.6, 0.5])
        np.testing.assert_allclose(precision, [1.0, 1.0, 2.0 / 3.0, 0.75, 0.6])
        np.testing.assert_allclose(recall, [0.2, 0.4, 0.4, 0.6, 0.6])
        self.assertAlmostEqual(evaluate.average_precision(precision, recall), 0.55)
        self.assertAlmostEqual(evaluate.recall_at_full_precision(precision, recall), 0.4)

    def test_tied_confidences_are_one_threshold(self):
        # 0.9 (hit) and 0.9 (miss) cannot be separated: first point P = 1/2, R = 1/3; then P = 2/3, R = 2/3
        # AP = 1/3 * 1/2 + 1/3 * 2/3 = 7/18; precision never reaches 1 -> recall at 100% precision 0
        thresholds, precision, recall = evaluate.precision_recall([0.9, 0.9, 0.5], [True, False, True], [True] * 3)
        np.testing.assert_allclose(thresholds, [0.9, 0.5])
        np.testing.assert_allclose(precision, [0.5, 2.0 / 3.0])
        np.testing.assert_allclose(recall, [1.0 / 3.0, 2.0 / 3.0])
        self.assertAlmostEqual(evaluate.average_precision(precision, recall), 7.0 / 18.0)
        self.assertEqual(evaluate.recall_at_full_precision(precision, recall), 0.0)

    def test_unanswered_queries_count_in_recall_only(self):
        # 4 queries, the 2nd has no answer (its confidence must be ignored): ranking hit(0.8), hit(0.3), miss(0.1)
        # recall over all 4: 1/4, 2/4, 2/4; precision 1, 1, 2/3
        _, precision, recall = evaluate.precision_recall([0.8, 0.99, 0.3, 0.1], [True, False, True, False],
                                                         [True, False, True, True])
        np.testing.assert_allclose(recall, [0.25, 0.5, 0.5])
        np.testing.assert_allclose(precision, [1.0, 1.0, 2.0 / 3.0])
        self.assertAlmostEqual(evaluate.recall_at_full_precision(precision, recall), 0.5)
        self.assertAlmostEqual(evaluate.average_precision(precision, recall), 0.5)

    def test_nothing_answered(self):
        _, precision, recall = evaluate.precision_recall([0.5, 0.4], [False, False], [False, False])
        self.assertEqual(evaluate.average_precision(precision, recall), 0.0)
        self.assertEqual(evaluate.recall_at_full_precision(precision, recall), 0.0)


class FrameErrorTest(unittest.TestCase):
    def test_integer_truth_and_no_answer(self):
        errors = evaluate.frame_errors([3, 7, -1, 0], [3, 5, 2, 1])
        np.testing.assert_array_equal(errors, [0, 2, np.inf, 1])

    def test_fractional_truth_accepts_both_neighbours(self):
        # exact 2.5: keyframes 2 and 3 are both right (0), 1 and 4 are one off; exact 3.0 behaves like integer 3
        errors = evaluate.frame_errors([2, 3, 4, 1, 5, -1], [0] * 6, [2.5, 2.5, 2.5, 2.5, 3.0, 2.5])
        np.testing.assert_array_equal(errors, [0, 0, 1, 1, 2, np.inf])

    def test_within_shares(self):
        shares = evaluate.within_shares([0, 1, 1, 3, 6, np.inf, 2, 0])
        self.assertEqual(shares, {0: 2 / 8, 1: 4 / 8, 2: 5 / 8, 5: 6 / 8})


class HomingTest(unittest.TestCase):
    def test_errors_and_signs(self):
        # used: rows 0-2 (row 3 has true shift 0, row 4 no answer): errors 0.2, 1.5, 0.0; signs right, wrong, right
        result = evaluate.homing_errors([1.2, -0.5, 2.0, 0.7, 3.0], [1.0, 1.0, 2.0, 0.0, -3.0],
                                        [True, True, True, True, False])
        self.assertEqual(result["count"], 3)
        self.assertAlmostEqual(result["median_abs_error_px"], 0.2)
        self.assertAlmostEqual(result["mean_abs_error_px"], 1.7 / 3.0)
        self.assertAlmostEqual(result["sign_agreement"], 2.0 / 3.0)

    def test_zero_estimate_is_wrong_sign(self):
        result = evaluate.homing_errors([0.0], [-1.0], [True])
        self.assertEqual(result["sign_agreement"], 0.0)


SIX_QUERIES = """query_index,keyframe,confidence,shift_px,homing_angle_rad,status
0,0,0.9,0.1,-0.003,tracking
1,1,0.8,0.0,0.0,tracking
2,5,0.95,0.0,0.0,lost
3,3,0.4,1.5,-0.05,tracking
4,-1,0.99,0.0,0.0,initializing
5,6,0.6,-2.5,0.08,tracking
"""


class BlindReferenceTest(unittest.TestCase):
    def test_a_blind_run_is_crossed_at_the_true_speed_before_it(self):
        # truth 0 1 2 3 | 4 4 4 4 (blind) | 5 6; window 2: from query 3 (keyframe 3) at (3 - 1) / 2 = 1 a query:
        # 4, 5, 6, 7 against 4, 4, 4, 4 -> errors 0, 1, 2, 3: two right. 6 seen + 2 = 8 of 10.
        truth = [0, 1, 2, 3, 4, 4, 4, 4, 5, 6]
        blind = [0, 0, 0, 0, 1, 1, 1, 1, 0, 0]
        self.assertAlmostEqual(evaluate.blind_reference(truth, blind, window=2), 0.8)
        # tolerance 0: only query 4 of the run
        self.assertAlmostEqual(evaluate.blind_reference(truth, blind, window=2, tolerance=0), 0.7)
        # a robot that stood before the run (keyframes 3 3 3): speed 0, the run answered 3: errors 1 1 1 1
        self.assertAlmostEqual(evaluate.blind_reference([0, 3, 3, 3, 4, 4, 4, 4, 5, 6], blind, window=2), 1.0)

    def test_a_fractional_speed_is_rounded_half_up_over_exactly_the_window(self):
        # truth 5 6 6 (speed over the last 2 steps: (6 - 5) / 2 = 0.5; over 1 step it would be 0), then 4 blind
        # queries: 6.5, 7, 7.5, 8 -> 7, 7, 8, 8 (half up; rounding half to even gives 6 and 8 for 6.5 and 7.5,
        # truncating 6 and 7). Against 7 7 8 8 at tolerance 0: all 4 right.
        truth, blind = [5, 6, 6, 7, 7, 8, 8], [0, 0, 0, 1, 1, 1, 1]
        self.assertAlmostEqual(evaluate.blind_reference(truth, blind, window=2, tolerance=0), 1.0)
        # speed 1/3 over 3 steps (truth 0 0 0 1): from 1, 1.33, 1.67, 2 -> 1, 2, 2 (rounding up: 2, 2, 2)
        truth, blind = [0, 0, 0, 1, 1, 2, 2], [0, 0, 0, 0, 1, 1, 1]
        self.assertAlmostEqual(evaluate.blind_reference(truth, blind, window=3, tolerance=0), 1.0)

    def test_a_run_without_a_step_before_it_takes_the_speed_after_it(self):
        # truth 5 5 5 6 (first three blind): the speed after the run is unknown (one query): 1 a query from 5,
        # reckoned 5, 6, 7 -> errors 0, 1, 2
        self.assertAlmostEqual(evaluate.blind_reference([5, 5, 5, 6], [1, 1, 1, 0]), 3 / 4)
        # map every 2nd frame: 0.5 a query over the 4 steps after the run (queries 4-8: 10 -> 12; the 5th step
        # jumps to 20), the run from 8 - 0.5: 8, 8.5, 9, 9.5 -> 8, 9, 9, 10, the truth; at 1 a query it would
        # answer 8, 9, 10, 11: two wrong
        truth = [8, 9, 9, 10, 10, 11, 11, 12, 12, 20]
        blind = [1, 1, 1, 1, 0, 0, 0, 0, 0, 0]
        self.assertAlmostEqual(evaluate.blind_reference(truth, blind, window=4, tolerance=0), 1.0)
        # after its first query alone (no step before it): the same rule, from that query's keyframe 8: 8.5, 9,
        # 9.5 -> 9, 9, 10 (at 1 a query: 9, 10, 11)
        self.assertAlmostEqual(evaluate.blind_reference([8, 9, 9, 10, 10, 11, 11, 12, 12], [0, 1, 1, 1, 0, 0, 0, 0, 0],
                                                        window=4, tolerance=0), 1.0)
        self.assertAlmostEqual(evaluate.blind_reference([3, 4, 5], [0, 0, 0]), 1.0)

    def test_fractional_truths_score_as_a_run_does(self):
        # true keyframe 2.5 (between 2 and 3): an answer of 2 or 3 is exact; the run reckoned 3 from 2 at 1
        self.assertAlmostEqual(evaluate.blind_reference([1, 2, 3], [0, 0, 1], window=1, tolerance=0,
                                                        exact=[np.nan, np.nan, 2.5]), 1.0)
        self.assertAlmostEqual(evaluate.blind_reference([1, 2, 2], [0, 0, 1], window=1, tolerance=0,
                                                        exact=[np.nan, np.nan, 1.6]), 2 / 3)


class EvaluateEndToEndTest(unittest.TestCase):
    """Six queries, identity truth, tolerance 1.

    errors 0, 0, 3, 0, no answer, 1 -> within 0: 3/6, within 1: 4/6, within 2: 4/6, within 5: 5/6.
    answered ranked by confidence: 0.95 miss, 0.9 hit, 0.8 hit, 0.6 hit, 0.4 hit; recall over 6 queries:
    precision 0, 1/2, 2/3, 3/4, 4/5 at recall 0, 1/6, 2/6, 3/6, 4/6
    -> AP = (1/2 + 2/3 + 3/4 + 4/5) / 6 = 0.4527777..., recall at 100% precision 0 (the top answer is wrong).
    """

    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="test_evaluate_")
        self.results = os.path.join(self.tmp, "results.csv")
        write(self.results, SIX_QUERIES)

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def run_main(self, args):
        out = io.StringIO()
        err = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = evaluate.main(args)
        return code, out.getvalue(), err.getvalue()

    def score(self, args):
        """Runs evaluate with --output-json; asserts exit 0; returns (metrics, stdout, stderr)."""
        json_path = os.path.join(self.tmp, "m.json")
        code, out, err = self.run_main(args + ["--output-json", json_path])
        self.assertEqual(code, 0, err)
        with open(json_path) as f:
            return json.load(f), out, err

    def check_six(self, m):
        self.assertEqual(m["queries"], 6)
        self.assertEqual(m["no_answer"], 1)
        self.assertAlmostEqual(m["within"]["0"], 3 / 6)
        self.assertAlmostEqual(m["within"]["1"], 4 / 6)
        self.assertAlmostEqual(m["within"]["2"], 4 / 6)
        self.assertAlmostEqual(m["within"]["5"], 5 / 6)
        self.assertAlmostEqual(m["average_precision"], (0.5 + 2 / 3 + 0.75 + 0.8) / 6)
        self.assertEqual(m["recall_at_100_precision"], 0.0)
        self.assertEqual(m["by_status"]["lost"], {"queries": 1, "wrong": 1})
        self.assertEqual(m["by_status"]["initializing"], {"queries": 1, "wrong": 1})
        self.assertEqual(m["by_status"]["tracking"], {"queries": 4, "wrong": 0})

    def test_identity(self):
        m, out, _ = self.score([self.results, "--identity"])
        self.check_six(m)
        self.assertIn("within 0/1/2/5 frames: 0.500 / 0.667 / 0.667 / 0.833", out)

    def test_ground_truth_file_with_teach_frame_and_shift(self):
        # the synthetic generator's columns; true shifts +1.0 on queries 3 and 5, 0 elsewhere:
        # query 3 estimates 1.5 (error 0.5, right sign), query 5 estimates -2.5 (error 3.5, wrong sign)
        # heading offsets 0.031 rad on q3 and q5: the homing angle should be -0.031
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,teach_frame,heading_offset_rad,expected_shift_px_64\n"
                  "0,0,0,0\n1,1,0,0\n2,2,0,0\n3,3,0.031,1.0\n4,4,0,0\n5,5,0.031,1.0\n")
        m, _, _ = self.score([self.results, "-g", gt])
        self.check_six(m)
        self.assertEqual(m["homing"]["count"], 2)
        self.assertAlmostEqual(m["homing"]["median_abs_error_px"], 2.0)
        self.assertAlmostEqual(m["homing"]["mean_abs_error_px"], 2.0)
        self.assertAlmostEqual(m["homing"]["sign_agreement"], 0.5)
        # homing angle should be -0.031: q3 -0.05 (error 0.019, right sign), q5 0.08 (error 0.111, wrong sign)
        self.assertAlmostEqual(m["homing"]["angle_median_abs_error_rad"], (0.019 + 0.111) / 2)
        self.assertAlmostEqual(m["homing"]["angle_sign_agreement"], 0.5)
        # unshifted answered queries 0, 1, 2: |shift| 0.1, 0, 0 -> median 0
        self.assertEqual(m["homing"]["zero_shift_count"], 3)
        self.assertAlmostEqual(m["homing"]["zero_shift_median_abs_px"], 0.0)

    def test_missing_rows_are_no_answers_and_dark_frames(self):
        # truth has 8 queries: 6 and 7 are missing from the results -> 3 no answers; dark: 2 (wrong) and 6 (missing)
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,keyframe,true_shift_px,query_dark\n" +
              "".join("%d,%d,0,%d\n" % (i, i, 1 if i in (2, 6) else 0) for i in range(8)))
        m, _, _ = self.score([self.results, "-g", gt])
        self.assertEqual(m["queries"], 8)
        self.assertEqual(m["no_answer"], 3)
        self.assertEqual(m["missing_rows"], 2)
        self.assertAlmostEqual(m["within"]["1"], 4 / 8)
        self.assertEqual(m["dark"]["queries"], 2)
        self.assertEqual(m["dark"]["wrong"], 2)
        self.assertAlmostEqual(m["dark"]["within_tolerance_not_dark"], 4 / 6)
        # explicit list overrides the column
        m, _, _ = self.score([self.results, "-g", gt, "--dark-frames", "0-1"])
        self.assertEqual(m["dark"]["queries"], 2)
        self.assertEqual(m["dark"]["wrong"], 0)

    def test_rows_without_ground_truth_are_named(self):
        # a ground truth of 4 of the 6 queries: rows 4 and 5 are not scored, and the user is told
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,keyframe\n" + "".join("%d,%d\n" % (i, i) for i in range(4)))
        m, _, err = self.score([self.results, "-g", gt])
        self.assertEqual(m["queries"], 4)
        self.assertEqual(m["rows_without_ground_truth"], 2)
        self.assertIn("2 of 6 result rows have no ground truth", err)
        _, _, err = self.score([self.results, "--identity"])
        self.assertNotIn("warning", err)

    def test_keyframe_dark_stationary_and_subsets(self):
        # queries 0-5 (errors 0, 0, 3, 0, no answer, 1): query 2 has a dark keyframe, 3 and 5 are stationary
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,keyframe,query_dark,keyframe_dark,query_stationary,keyframe_stationary\n"
                  "0,0,0,0,0,0\n1,1,0,0,0,0\n2,2,0,1,0,0\n3,3,0,0,1,0\n4,4,0,0,0,0\n5,5,0,0,0,1\n")
        m, out, _ = self.score([self.results, "-g", gt])
        self.check_six(m)   # all-query figures are unchanged
        self.assertEqual(m["dark"]["queries"], 1)
        self.assertEqual(m["dark"]["wrong"], 1)
        self.assertEqual(m["stationary"], {"queries": 2, "not_dark": 2, "wrong": 0, "wrong_not_dark": 0})
        # not dark: queries 0, 1, 3, 4, 5 with errors 0, 0, 0, none, 1; ranked 0.9 hit, 0.8 hit, 0.6 hit, 0.4 hit
        nd = m["not_dark"]
        self.assertEqual(nd["queries"], 5)
        self.assertAlmostEqual(nd["within"]["0"], 3 / 5)
        self.assertAlmostEqual(nd["within"]["1"], 4 / 5)
        self.assertAlmostEqual(nd["recall_at_100_precision"], 4 / 5)
        self.assertAlmostEqual(nd["average_precision"], 4 / 5)
        # neither: queries 0, 1, 4 -> 2 hits of 3, the top answers right
        nn = m["not_dark_not_stationary"]
        self.assertEqual(nn["queries"], 3)
        self.assertAlmostEqual(nn["within"]["1"], 2 / 3)
        self.assertAlmostEqual(nn["recall_at_100_precision"], 2 / 3)
        self.assertIn("excluding dark and stationary (3 queries)", out)
        # blind (dark or standing keyframe): queries 2 and 5. Query 2 from query 1 at the speed of queries 0-1
        # (1 a query): 2, right; query 5 from query 4: 5, right. Every other query counts as right: 6 of 6.
        self.assertEqual(m["blind_reference"]["blind_queries"], 2)
        self.assertAlmostEqual(m["blind_reference"]["within_tolerance"], 1.0)

    def test_the_blind_reference_reads_the_standing_keyframes(self):
        # the teach camera stood at keyframe 3 for queries 3-5: dead-reckoned from query 2 at the true speed of
        # queries 0-2 (1 a query): 3, 4, 5 against 3, 3, 3 -> two right; 5 of 6 (the run's answers do not matter)
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,keyframe,query_stationary,keyframe_stationary\n"
                  "0,0,0,0\n1,1,0,0\n2,2,0,0\n3,3,0,1\n4,3,0,1\n5,3,0,1\n")
        m, out, _ = self.score([self.results, "-g", gt])
        self.assertEqual(m["blind_reference"]["blind_queries"], 3)
        self.assertAlmostEqual(m["blind_reference"]["within_tolerance"], 5 / 6)
        self.assertIn("dead-reckoned at the true mean speed over the 10 steps before them: within tolerance 0.833",
                      out)
        m, _, _ = self.score([self.results, "-g", gt, "--tolerance", "0"])   # the run's query 3 alone
        self.assertAlmostEqual(m["blind_reference"]["within_tolerance"], 4 / 6)
        # a fractional truth for query 3 (3.6: the answer 3 is one off) is scored as the run's answers are
        write(gt, "query_index,keyframe,keyframe_exact,query_stationary,keyframe_stationary\n"
                  "0,0,,0,0\n1,1,,0,0\n2,2,,0,0\n3,3,3.6,0,1\n4,3,,0,1\n5,3,,0,1\n")
        m, _, _ = self.score([self.results, "-g", gt, "--tolerance", "0"])
        self.assertAlmostEqual(m["blind_reference"]["within_tolerance"], 3 / 6)
        m, _, _ = self.score([self.results, "--identity"])
        self.assertNotIn("blind_reference", m)

    def test_wrong_answers_at_another_copy_of_the_true_place(self):
        # answers 0, 1, 5, 3, none, 6. The teach camera stood at keyframes 4-7 (rows naming them with
        # keyframe_stationary 1). Query 2: truth 7, answer 5, two off: 5, 6, 7 all standing, a copy. Query 3:
        # truth 6, answer 3: keyframe 3 is not standing, not a copy. Query 4: no answer. Query 5: right.
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,keyframe,keyframe_stationary\n0,0,0\n1,1,0\n2,7,1\n3,6,1\n4,4,1\n5,5,1\n")
        m, out, _ = self.score([self.results, "-g", gt])
        self.assertEqual(m["copies"], {"wrong": 3, "wrong_at_copy": 1, "within_tolerance_or_copy": 4 / 6})
        self.assertIn("the ground truth's frame alignment picks one): 1 of 3; within tolerance or at such a copy: "
                      "0.667", out)
        # keyframe 6 marked as not standing (query 3's row): the run from 5 to 7 is broken inside, no copy
        write(gt, "query_index,keyframe,keyframe_stationary\n0,0,0\n1,1,0\n2,7,1\n3,6,0\n4,4,1\n5,5,1\n")
        m, _, _ = self.score([self.results, "-g", gt])
        self.assertEqual(m["copies"]["wrong_at_copy"], 0)
        # keyframe 6 named by no row: not known to be standing either
        write(gt, "query_index,keyframe,keyframe_stationary\n0,0,0\n1,1,0\n2,7,1\n3,8,1\n4,4,1\n5,5,1\n")
        m, _, _ = self.score([self.results, "-g", gt])
        self.assertEqual(m["copies"]["wrong_at_copy"], 0)
        m, _, _ = self.score([self.results, "--identity"])
        self.assertNotIn("copies", m)

    def test_tolerance_zero(self):
        m, _, _ = self.score([self.results, "--identity", "--tolerance", "0"])
        # hits now 0.9, 0.8, 0.4 (q5 is one off): precision 0, 1/2, 2/3, 2/4, 3/5 at recall 0, 1/6, 2/6, 2/6, 3/6
        self.assertAlmostEqual(m["average_precision"], (0.5 + 2 / 3 + 0.6) / 6)

    def test_plots_and_cost_matrix(self):
        plots = os.path.join(self.tmp, "plots")
        cost = os.path.join(self.tmp, "cost.npy")
        np.save(cost, np.arange(6 * 7, dtype=np.float32).reshape(6, 7))
        code, _, _ = self.run_main([self.results, "--identity", "--plots", plots, "--cost-matrix", cost])
        self.assertEqual(code, 0)
        for name in ("matches.png", "precision_recall.png", "cost_matrix.png"):
            self.assertGreater(os.path.getsize(os.path.join(plots, name)), 1000, name)

    def test_plots_given_a_file_is_refused_by_name(self):
        # it was "[Errno 17] File exists: 'res.csv'"
        with contextlib.redirect_stderr(io.StringIO()) as err:
            with self.assertRaises(SystemExit) as caught:
                evaluate.main([self.results, "--identity", "--plots", self.results])
        self.assertEqual(caught.exception.code, 2)
        self.assertIn("--plots names a folder for the plots; %s is a file" % self.results, err.getvalue())

    def test_a_bad_cost_matrix_is_refused_or_named(self):
        plots = os.path.join(self.tmp, "plots")
        cost = os.path.join(self.tmp, "cost.npy")
        for matrix, message in ((np.zeros((2, 2, 2)), "has 3 dimensions 2x2x2; it must be 2 (queries x keyframes)"),
                                (np.full((6, 7), np.nan), "holds no finite value")):
            np.save(cost, matrix)
            code, _, err = self.run_main([self.results, "--identity", "--plots", plots, "--cost-matrix", cost])
            self.assertEqual(code, 2, message)
            self.assertIn(message, err)
        np.save(cost, np.zeros((5, 7)))
        code, _, err = self.run_main([self.results, "--identity", "--plots", plots, "--cost-matrix", cost])
        self.assertEqual(code, 0, err)
        self.assertIn("has 5 rows for 6 result rows; only the queries it holds are drawn", err)

    def test_an_output_that_names_an_input_is_refused_and_the_input_kept(self):
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,keyframe\n" + "".join("%d,%d\n" % (i, i) for i in range(6)))
        link = os.path.join(self.tmp, "link.csv")
        os.symlink(self.results, link)
        for args, message in (([self.results, "-g", gt, "--output-json", gt],
                               "--output-json '%s' names the same file as --ground-truth" % gt),
                              ([self.results, "--identity", "--output-json", link],
                               "--output-json '%s' names the same file as the results CSV" % link),
                              ([self.results, "--identity", "--plots", self.tmp, "--cost-matrix",
                                os.path.join(self.tmp, "matches.png")],
                               "--plots '%s' names the same file as --cost-matrix" % os.path.join(self.tmp, "matches.png"))):
            with contextlib.redirect_stderr(io.StringIO()) as err:
                with self.assertRaises(SystemExit) as caught:
                    evaluate.main(args)
            self.assertEqual(caught.exception.code, 2, args)
            self.assertIn(message, err.getvalue())
        with open(self.results) as f:
            self.assertEqual(f.read(), SIX_QUERIES)
        with open(gt) as f:
            self.assertTrue(f.read().startswith("query_index,keyframe\n0,0\n"))

    def test_a_keyframe_below_minus_one_is_refused_and_a_confidence_outside_0_1_named(self):
        bad = os.path.join(self.tmp, "bad.csv")
        write(bad, SIX_QUERIES.replace("3,3,0.4,", "3,-7,0.4,"))
        code, _, err = self.run_main([bad, "--identity"])
        self.assertEqual(code, 2)
        self.assertIn("row 5: keyframe must be >= 0, or -1 for no answer, not -7", err)
        write(bad, SIX_QUERIES.replace("3,3,0.4,", "3,3,1.7,"))
        code, _, err = self.run_main([bad, "--identity"])
        self.assertEqual(code, 0, err)
        self.assertIn("1 confidence(s) outside [0, 1]", err)

    def test_bad_input_exits_nonzero(self):
        bad = os.path.join(self.tmp, "bad.csv")
        write(bad, "query_index,keyframe\n0,0\n")
        self.assertEqual(self.run_main([bad, "--identity"])[0], 2)
        self.assertEqual(self.run_main([os.path.join(self.tmp, "nothing.csv"), "--identity"])[0], 2)
        write(bad, "query_index,keyframe,confidence\n")
        self.assertEqual(self.run_main([bad, "--identity"])[0], 2)
        gt = os.path.join(self.tmp, "gt.csv")
        write(gt, "query_index,place\n0,0\n")
        code, _, err = self.run_main([self.results, "-g", gt])
        self.assertEqual(code, 2)
        self.assertIn("keyframe or teach_frame", err)

    def test_a_confidence_that_cannot_be_ranked_is_refused(self):
        for value in ("nan", "inf", "-inf"):
            bad = os.path.join(self.tmp, "bad.csv")
            write(bad, SIX_QUERIES.replace("3,3,0.4,", "3,3,%s," % value))
            code, _, err = self.run_main([bad, "--identity"])
            self.assertEqual(code, 2, value)
            self.assertIn("row 5: confidence must be a finite number", err)

    def test_a_row_cut_short_or_too_long_is_refused_by_row(self):
        # A results file cut while written ends inside a row: it was scored as if complete.
        lines = SIX_QUERIES.strip().splitlines()
        cut = os.path.join(self.tmp, "cut.csv")
        write(cut, "\n".join(lines[:5]) + "\n" + ",".join(lines[5].split(",")[:3]) + "\n")
        code, _, err = self.run_main([cut, "--identity"])
        self.assertEqual(code, 2)
        self.assertIn("cut.csv, row 6 has 3 values for the 6 columns of its header", err)
        long_row = os.path.join(self.tmp, "long.csv")
        write(long_row, SIX_QUERIES.replace("3,3,0.4,", "3,3,0.4,7,", 1))
        code, _, err = self.run_main([long_row, "--identity"])
        self.assertEqual(code, 2)
        self.assertIn("has 7 values for the 6 columns of its header", err)

    def test_a_binary_file_or_a_huge_keyframe_is_refused_not_a_traceback(self):
        binary = os.path.join(self.tmp, "binary.csv")
        with open(binary, "wb") as f:
            f.write(b"query_index,keyframe,confidence\n0,0,0.5\n\xff\xfe\x00\x81")
        code, _, err = self.run_main([binary, "--identity"])
        self.assertEqual(code, 2)
        self.assertIn("is not a text CSV file", err)
        for value in ("inf", "1e30", "nan"):
            bad = os.path.join(self.tmp, "huge.csv")
            write(bad, SIX_QUERIES.replace("3,3,0.4,", "3,%s,0.4," % value))
            code, _, err = self.run_main([bad, "--identity"])
            self.assertEqual(code, 2, value)
            self.assertIn("row 5: column keyframe is not", err)

    def test_dark_frames_that_are_not_queries_are_refused(self):
        # The six queries are 0 .. 5: frame 9 cannot be dark here (a list meant for another run).
        code, _, err = self.run_main([self.results, "--identity", "--dark-frames", "2,9"])
        self.assertEqual(code, 2)
        self.assertIn("1 frame(s) that are not queries here (9)", err)
        self.assertEqual(self.run_main([self.results, "--identity", "--dark-frames", "4-2"])[0], 2)
        m, _, _ = self.score([self.results, "--identity", "--dark-frames", "2,5"])
        self.assertEqual(m["dark"]["queries"], 2)


def localization_messages_available():
    try:
        import rosbag  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
        from along_route_localization.msg import Localization  # noqa: F401
    except ImportError:
        return False
    return True


@unittest.skipUnless(localization_messages_available(),
                     "needs the ROS Python modules and this package's messages (source the workspace)")
class BagInputTest(unittest.TestCase):
    """A run of the nodelets: the six queries above as 6 camera frames in a bag and their Localization
    messages in another (query 4, no answer in the CSV, got none), matched by the camera stamp; scored as
    the CSV."""

    run_main = EvaluateEndToEndTest.run_main
    score = EvaluateEndToEndTest.score

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def same_scores(self, bag_metrics, csv_metrics):
        for key in ("queries", "no_answer", "within", "recall_at_100_precision", "average_precision", "homing"):
            self.assertEqual(json.dumps(bag_metrics[key], sort_keys=True), json.dumps(csv_metrics[key], sort_keys=True),
                             key)
        self.assertAlmostEqual(bag_metrics["within"]["1"], 4 / 6)  # EvaluateEndToEndTest's hand-worked figures
        self.assertAlmostEqual(bag_metrics["average_precision"], (1 / 2 + 2 / 3 + 3 / 4 + 4 / 5) / 6)

    def setUp(self):
        import rosbag
        import rospy
        from sensor_msgs.msg import Image
        from along_route_localization.msg import Localization
        self.tmp = tempfile.mkdtemp(prefix="test_evaluate_bags_")
        self.results = os.path.join(self.tmp, "results.csv")
        write(self.results, SIX_QUERIES)
        self.query_bag = os.path.join(self.tmp, "repeat.bag")
        self.localization_bag = os.path.join(self.tmp, "localization.bag")
        stamps = [rospy.Time(10, 100000000 * i) for i in range(6)]
        with rosbag.Bag(self.query_bag, "w") as bag:
            for stamp in stamps:
                image = Image(height=1, width=1, encoding="mono8", step=1, data=b"\x00")
                image.header.stamp = stamp
                bag.write("/camera/image_raw", image, stamp)
        codes = {"initializing": 0, "tracking": 1, "lost": 2}
        rows = [line.split(",") for line in SIX_QUERIES.strip().splitlines()[1:]]
        with rosbag.Bag(self.localization_bag, "w") as bag:
            for i, keyframe, confidence, shift, angle, status in rows:
                if i == "4":
                    continue  # no message for this frame
                m = Localization(keyframe=int(keyframe), confidence=float(confidence), shift=float(shift),
                                 homing_angle=float(angle), status=codes[status])
                m.header.stamp = stamps[int(i)]
                bag.write("/localization", m, stamps[int(i)])
            stray = Localization(keyframe=3, confidence=0.5)
            stray.header.stamp = rospy.Time(99)  # from another drive: matches no frame
            bag.write("/localization", stray, rospy.Time(99))

    def bags(self, *extra):
        return ["--localization-bag", self.localization_bag, "--query-bag", self.query_bag] + list(extra)

    def test_a_run_of_the_nodelets_scores_as_its_csv(self):
        written = os.path.join(self.tmp, "written.csv")
        m, out, _ = self.score(self.bags("--identity", "--write-results", written))
        from_csv, _, _ = self.score([self.results, "--identity"])
        self.same_scores(m, from_csv)
        self.assertIn("evaluate: 5 of 6 query frames have a Localization message; 1 messages match no frame of "
                      + self.query_bag, out)
        self.assertEqual(m["results"], {"localization_bag": self.localization_bag, "query_bag": self.query_bag})
        with open(written) as f:
            lines = f.read().splitlines()
        self.assertEqual(lines[0], "query_index,keyframe,confidence,shift_px,homing_angle_rad,status")
        self.assertEqual(lines[5], "4,-1,0.0,0.0,0.0,no_message")
        self.assertTrue(lines[3].startswith("2,5,0.949999") and lines[3].endswith(",lost"), lines[3])
        # The written file scores the same as the bags.
        again, _, _ = self.score([written, "--identity"])
        self.same_scores(again, from_csv)

    def test_a_compressed_camera_bag_scores_as_its_csv(self):
        # The camera recorded through image_transport's compressed plugin: sensor_msgs/CompressedImage, whose
        # header stamps the Localization messages carry as well. It was "no sensor_msgs/Image topic".
        import rosbag
        from sensor_msgs.msg import CompressedImage
        compressed_bag = os.path.join(self.tmp, "repeat_compressed.bag")
        with rosbag.Bag(self.query_bag) as source, rosbag.Bag(compressed_bag, "w") as target:
            for _, image, t in source.read_messages():
                msg = CompressedImage(format="png", data=b"\x89PNG")
                msg.header.stamp = image.header.stamp
                target.write("/camera/image_raw/compressed", msg, t)
        m, _, _ = self.score(["--localization-bag", self.localization_bag, "--query-bag", compressed_bag,
                              "--identity"])
        from_csv, _, _ = self.score([self.results, "--identity"])
        self.same_scores(m, from_csv)

    def test_topics_are_found_or_named(self):
        import rosbag
        from sensor_msgs.msg import Image
        with rosbag.Bag(self.query_bag, "a") as bag:
            image = Image(height=1, width=1, encoding="mono8", step=1, data=b"\x00")
            bag.write("/other_camera/image_raw", image, image.header.stamp)
        code, _, err = self.run_main(self.bags("--identity"))
        self.assertEqual(code, 2)
        self.assertIn("has 2 sensor_msgs/Image or sensor_msgs/CompressedImage topics (/camera/image_raw, "
                      "/other_camera/image_raw): name one with "
                      "--camera-topic", err)
        m, _, _ = self.score(self.bags("--identity", "--camera-topic", "/camera/image_raw"))
        self.assertAlmostEqual(m["within"]["1"], 4 / 6)
        code, _, err = self.run_main(self.bags("--identity", "--camera-topic", "/camera/image_raw",
                                               "--localization-topic", "/camera/image_raw"))
        self.assertEqual(code, 2)
        self.assertIn("localization.bag has no topic /camera/image_raw (has /localization)", err)
        code, _, err = self.run_main(["--identity", "--localization-bag", self.query_bag, "--query-bag", self.query_bag,
                                      "--camera-topic", "/camera/image_raw", "--localization-topic", "/camera/image_raw"])
        self.assertEqual(code, 2)
        self.assertIn("topic /camera/image_raw holds sensor_msgs/Image, not along_route_localization/Localization", err)

    def test_frames_with_one_stamp_are_refused(self):
        import rosbag
        import rospy
        from sensor_msgs.msg import Image
        with rosbag.Bag(self.query_bag, "a") as bag:
            image = Image(height=1, width=1, encoding="mono8", step=1, data=b"\x00")
            image.header.stamp = rospy.Time(10, 200000000)  # frame 2's stamp again
            bag.write("/camera/image_raw", image, image.header.stamp)
        code, _, err = self.run_main(self.bags("--identity"))
        self.assertEqual(code, 2)
        self.assertIn("frames 2 and 3 of /camera/image_raw have the same stamp", err)  # the bag is read in time order

    def localizations_with(self, message_index, field, value):
        """A copy of the localization bag (localization_bad.bag) whose message message_index has field = value."""
        import rosbag
        path = os.path.join(self.tmp, "localization_bad.bag")
        with rosbag.Bag(self.localization_bag) as bag, rosbag.Bag(path, "w") as out:
            for n, (topic, m, t) in enumerate(bag.read_messages()):
                if n == message_index:
                    setattr(m, field, value)
                out.write(topic, m, t)
        return path

    def test_a_message_the_csv_would_refuse_is_refused(self):
        for field, value, message in (
                ("confidence", float("nan"), ": confidence must be a finite number, not nan"),
                ("status", 9, " has status 9, not one of 0 initializing, 1 tracking, 2 lost, 3 end_of_route"),
                ("keyframe", -7, ": keyframe must be >= 0, or -1 for no answer, not -7")):
            bad = self.localizations_with(1, field, value)
            code, _, err = self.run_main(["--localization-bag", bad, "--query-bag", self.query_bag, "--identity"])
            self.assertEqual(code, 2, field)
            self.assertIn("message 1 of /localization (frame 1)" + message, err)

    def test_a_recording_of_a_looping_play_is_refused(self):
        import rosbag
        with rosbag.Bag(self.localization_bag) as bag:
            first = next(m for _, m, _ in bag.read_messages())
        with rosbag.Bag(self.localization_bag, "a") as bag:  # the first frame answered again, a loop later
            first.keyframe = 4
            bag.write("/localization", first, first.header.stamp + rospy_duration(100))
        code, _, err = self.run_main(self.bags("--identity"))
        self.assertEqual(code, 2)
        self.assertIn("messages 0 and 6 of /localization answer frame 0 of %s: the recording holds more than one "
                      "run of that bag (a looping rosbag play?)" % self.query_bag, err)

    def test_either_a_csv_or_both_bags(self):
        for args, message in ((["--identity", "--query-bag", self.query_bag],
                               "--localization-bag and --query-bag go together"),
                              ([self.results, "--identity"] + self.bags(),
                               "give either results.csv or --localization-bag with --query-bag"),
                              (["--identity"], "give either results.csv or --localization-bag with --query-bag"),
                              ([self.results, "--identity", "--write-results", os.path.join(self.tmp, "x.csv")],
                               "--write-results go with --localization-bag")):
            with contextlib.redirect_stderr(io.StringIO()) as err:
                with self.assertRaises(SystemExit) as caught:
                    evaluate.main(args)
            self.assertEqual(caught.exception.code, 2, args)
            self.assertIn(message, err.getvalue())


def rospy_duration(seconds):
    import rospy
    return rospy.Duration(seconds)


class IndexListTest(unittest.TestCase):
    def test_ranges(self):
        self.assertEqual(evaluate.parse_index_list("3,7,10-12"), [3, 7, 10, 11, 12])

    def test_file(self):
        with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
            f.write("4\n# comment\n9\n")
        try:
            self.assertEqual(evaluate.parse_index_list(f.name), [4, 9])
        finally:
            os.remove(f.name)

    def test_malformed(self):
        with self.assertRaises(evaluate.InputError):
            evaluate.parse_index_list("3,x")
        with self.assertRaises(evaluate.InputError):
            evaluate.parse_index_list("12-10")


if __name__ == "__main__":
    unittest.main()
