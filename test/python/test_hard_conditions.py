"""The hard conditions of generate_route as an independent check of the localizer (issue 30, "weak evidence
is not contrary evidence"), and run_hard_conditions' scoring.

One short route (seed 1, the generator's default seed; 200 teach frames at 320x240, about 25 s) with all
three conditions, run through localize_offline with its defaults. Through each condition's stretch the
images neither confirm nor contradict the track (low-texture: nothing to see; glare and contrast
collapse: the query washed out while the map is not), so:
  - no frame there is `lost` (lost means contradicted, not unconfirmed);
  - no answer there is more than half the stretch's length (in keyframes) from the truth: the estimate
    may drift while the robot changes speed unseen, but an answer further off than that has left the
    stretch, a jump, not a drift;
  - within one keyframe again at most 15 frames after the stretch: half the 30-frame sequence window
    (ring_buffer_rows), by when the frames after it outweigh the stretch's in the window; and in the 20
    frames after it no answer further off than inside it (a loss declared once the images are back must
    not send the answer far away: measured on other seeds, doc/results.md).
"""

import argparse
import contextlib
import csv
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import SCRIPTS_DIR, built_executable, load  # noqa: E402

RUNNER = built_executable('localize_offline')
run_hard_conditions = load('run_hard_conditions')

try:
    import cv2  # noqa: F401
except ImportError:  # pragma: no cover - depends on the machine
    cv2 = None

WINDOW_FRAMES = 30          # localize_offline's default ring_buffer_rows (K)
REGAIN_FRAMES = WINDOW_FRAMES // 2
STEP_M = 0.5                # generate_route's default --step-m: metres per keyframe


def render_route(output, teach_frames, width, height, *extra):
    """generate_route --seed 1 into `output` as images (no bags), `extra` its further arguments."""
    done = subprocess.run([sys.executable, os.path.join(SCRIPTS_DIR, 'generate_route'), '--output', output,
                           '--seed', '1', '--teach-frames', str(teach_frames), '--width', str(width), '--height',
                           str(height), '--images', '--no-bags', '--progress', 'off'] + list(extra),
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, timeout=300)
    if done.returncode != 0:
        raise RuntimeError('generate_route failed: %s' % done.stderr)


class ScoreTest(unittest.TestCase):
    """run_hard_conditions.score on hand-made rows."""

    def test_figures_per_stretch(self):
        truth = [dict(query_index=str(i), teach_frame=str(i), condition='glare' if 3 <= i <= 6 else '')
                 for i in range(12)]
        answers = {0: (0, 'tracking'), 1: (1, 'tracking'), 2: (2, 'tracking'), 3: (5, 'tracking'),
                   4: (40, 'lost'), 5: (-1, 'lost'), 6: (6, 'tracking'), 7: (10, 'tracking'),
                   8: (8, 'tracking'), 9: (9, 'lost'), 10: (10, 'tracking')}   # 11: no row at all
        results = [dict(query_index=str(i), keyframe=str(k), status=s) for i, (k, s) in answers.items()]
        figures = run_hard_conditions.score(truth, results, after_frames=4)
        glare = figures['conditions']['glare']
        # frames 3-6: within one only 6 (3 is 2 off, 4 is 36 off, 5 unanswered)
        self.assertEqual((glare['first'], glare['last'], glare['frames']), (3, 6, 4))
        self.assertAlmostEqual(glare['within_one'], 0.25)
        self.assertEqual((glare['lost'], glare['longest_lost_run'], glare['unanswered']), (2, 2, 1))
        self.assertEqual(glare['max_error'], 36)
        # after: 7 is 3 off, 8 right -> regained after 1 frame; next 4 frames 7-10: 8, 9, 10 within one
        self.assertEqual(glare['regained_after'], 1)
        self.assertAlmostEqual(glare['within_one_after'], 0.75)
        self.assertEqual(glare['lost_before'], 0)       # frames 0-2
        self.assertEqual(glare['max_error_after'], 3)   # frame 7
        overall = figures['overall']
        self.assertEqual(overall['frames'], 12)
        self.assertAlmostEqual(overall['within_one'], 7 / 12.0)   # 0, 1, 2, 6, 8, 9 (lost, but right), 10
        self.assertEqual((overall['lost'], overall['longest_lost_run']), (3, 2))

    def test_never_regained(self):
        truth = [dict(query_index=str(i), teach_frame=str(i), condition='low-texture' if i < 2 else '')
                 for i in range(4)]
        results = [dict(query_index=str(i), keyframe=str(i + 5), status='tracking') for i in range(4)]
        stretch = run_hard_conditions.score(truth, results)['conditions']['low-texture']
        self.assertIsNone(stretch['regained_after'])
        self.assertEqual(stretch['within_one_after'], 0.0)
        self.assertEqual(stretch['after_frames'], 2)
        truth = [dict(query_index=str(i), teach_frame=str(i), condition='glare' if i >= 3 else '') for i in range(5)]
        results = [dict(query_index=str(i), keyframe=str(i), status='lost' if i in (0, 2) else 'tracking')
                   for i in range(5)]
        self.assertEqual(run_hard_conditions.score(truth, results, after_frames=2)['conditions']['glare']
                         ['lost_before'], 1)   # frames 1-2


@unittest.skipIf(RUNNER is None or cv2 is None,
                 'localize_offline not built in a sourced workspace (source devel/setup.bash), or no cv2')
class HardConditionsTrackTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix='hard_conditions_test_')
        route = os.path.join(cls.tmp, 'route')
        render_route(route, 200, 320, 240, '--conditions', 'all')
        results = os.path.join(cls.tmp, 'results.csv')
        done = subprocess.run([RUNNER, '--quiet', '--map', os.path.join(route, 'teach_images'), '--query',
                               os.path.join(route, 'repeat_images'), '--output', results],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, timeout=300)
        if done.returncode != 0:
            raise RuntimeError('localize_offline failed: %s' % done.stderr)
        with open(os.path.join(route, 'ground_truth.csv'), newline='') as f:
            cls.truth = list(csv.DictReader(f))
        with open(results, newline='') as f:
            cls.results = {int(row['query_index']): row for row in csv.DictReader(f)}

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def frames(self, condition):
        """(query, truth, keyframe, status) of every repeat frame in the condition's stretch, and the frames
        after it."""
        rows = [(int(g['query_index']), int(g['teach_frame']), int(self.results[int(g['query_index'])]['keyframe']),
                 self.results[int(g['query_index'])]['status'], g['condition']) for g in self.truth]
        inside = [k for k, row in enumerate(rows) if row[4] == condition]
        self.assertGreater(len(inside), 5, condition)
        self.assertEqual(inside, list(range(inside[0], inside[-1] + 1)), 'one contiguous stretch')
        return [r[:4] for r in rows[inside[0]:inside[-1] + 1]], [r[:4] for r in rows[inside[-1] + 1:]]

    def check_no_loss(self, condition):
        inside, _ = self.frames(condition)
        lost = [q for q, _, _, status in inside if status == 'lost']
        self.assertEqual(lost, [], '%s: frames reported lost inside the stretch (queries %d-%d)'
                         % (condition, inside[0][0], inside[-1][0]))

    def check_no_jump_and_regained(self, condition):
        inside, after = self.frames(condition)
        span_keyframes = inside[-1][1] - inside[0][1] + 1
        bound = max(2, span_keyframes // 2)
        far = [(q, k - t) for q, t, k, _ in inside if k < 0 or abs(k - t) > bound]
        self.assertEqual(far, [], '%s: answers more than %d keyframes from the truth (query, error)'
                         % (condition, bound))
        self.assertGreaterEqual(len(after), REGAIN_FRAMES, 'route too short after the stretch')
        regained = next((n for n, (_, t, k, _) in enumerate(after) if k >= 0 and abs(k - t) <= 1), None)
        self.assertIsNotNone(regained, '%s: never within one again' % condition)
        self.assertLessEqual(regained, REGAIN_FRAMES, '%s: within one again only %s frames after the stretch'
                             % (condition, regained))
        far = [(q, k - t) for q, t, k, _ in after[:20] if k < 0 or abs(k - t) > bound]
        self.assertEqual(far, [], '%s: answers after the stretch more than %d keyframes from the truth (query, '
                         'error)' % (condition, bound))

    # Failed with the defaults before 2026-11-27 (twenty-first round): queries 142-151 of the 52-frame stretch
    # (queries 139-190, keyframes 123-160) were `lost`, one run of 10 frames, after the robot stood still at
    # keyframe 122 with only the plain in view and the estimate moved on to +7 keyframes. Weak evidence now
    # makes the estimate coast (loss_needs_contradiction true), and the checks while it coasts place the
    # robot where the images put it: none lost.
    def test_low_texture_keeps_tracking(self):
        self.check_no_loss('low-texture')

    def test_low_texture_no_jump_and_regained(self):
        self.check_no_jump_and_regained('low-texture')

    def test_glare_keeps_tracking(self):
        self.check_no_loss('glare')

    def test_glare_no_jump_and_regained(self):
        self.check_no_jump_and_regained('glare')

    def test_contrast_collapse_keeps_tracking(self):
        self.check_no_loss('contrast-collapse')

    def test_contrast_collapse_no_jump_and_regained(self):
        self.check_no_jump_and_regained('contrast-collapse')


@unittest.skipIf(RUNNER is None or cv2 is None,
                 'localize_offline not built in a sourced workspace (source devel/setup.bash), or no cv2')
class SetReachesTheRunnerTest(unittest.TestCase):
    """run_hard_conditions --set NAME=VALUE: every run of localize_offline gets the parameter."""

    @classmethod
    def setUpClass(cls):
        # A short route without conditions (40 teach frames at 160x120, a few seconds), where --reuse finds it.
        cls.work = tempfile.mkdtemp(prefix='hard_conditions_set_')
        render_route(os.path.join(cls.work, 'seed1_none'), 40, 160, 120)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.work, ignore_errors=True)

    def run_main(self, *sets):
        """run_hard_conditions.main on the route, with `--set` for each of sets: (exit code, stdout, stderr,
        the JSON entry of the run, the first answer's keyframe)."""
        json_path = os.path.join(self.work, 'figures.json')
        argv = ['--work', self.work, '--seeds', '1', '--sets', 'none', '--reuse', '--teach-frames', '40',
                '--localize-offline', RUNNER, '--output-json', json_path]
        for assignment in sets:
            argv += ['--set', assignment]
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = run_hard_conditions.main(argv)
        if code != 0:
            return code, out.getvalue(), err.getvalue(), None, None
        with open(json_path) as f:
            entry = json.load(f)[0]
        with open(os.path.join(self.work, 'seed1_none', 'results.csv'), newline='') as f:
            first = int(next(csv.DictReader(f))['keyframe'])
        return code, out.getvalue(), err.getvalue(), entry, first

    def test_a_known_start_elsewhere_reaches_the_localizer(self):
        # The repeat starts at teach frame 0, and so does the localizer by default (start_keyframe 0): its
        # first answer is keyframe 0. Told the robot starts at keyframe 20 and only moves as it drives
        # (detect_kidnapping false), its first answer is keyframe 20, the start it was given.
        code, out, _, entry, first = self.run_main()
        self.assertEqual(code, 0)
        self.assertEqual((entry['parameters'], first), ([], 0))
        self.assertNotIn('localize_offline with', out)
        code, out, _, entry, first = self.run_main('start_keyframe=20', 'detect_kidnapping=false')
        self.assertEqual(code, 0)
        self.assertEqual((entry['parameters'], first), (['start_keyframe=20', 'detect_kidnapping=false'], 20))
        self.assertIn('localize_offline with start_keyframe=20, detect_kidnapping=false', out)

    def test_an_unknown_parameter_is_the_runner_s_error(self):
        code, _, err, _, _ = self.run_main('no_such_parameter=1')
        self.assertEqual(code, 2)
        self.assertIn("unknown parameter 'no_such_parameter'", err)

    def refused(self, *options):
        """stderr of main(--work WORK --reuse OPTIONS), which must refuse them (argparse's exit 2)."""
        err = io.StringIO()
        with contextlib.redirect_stderr(err), self.assertRaises(SystemExit) as raised:
            run_hard_conditions.main(['--work', self.work, '--reuse'] + list(options))
        self.assertEqual(raised.exception.code, 2)
        return err.getvalue()

    def test_a_seed_range_past_the_bound_is_refused(self):
        # 1-100000000 built the list and ran out of memory (a traceback).
        self.assertIn("(at most 1000 seeds)", self.refused('--seeds', '1-100000000'))

    def test_reuse_takes_only_a_route_of_the_teach_frames_asked_for(self):
        # --reuse --teach-frames 300 scored this 40-frame route without a word. It is rendered anew then;
        # here the runner is run up to that point only (a route of 300 frames takes a minute).
        calls = []

        def fake_run(command, **kwargs):
            calls.append(command)
            raise RuntimeError('stop here')
        real_run = run_hard_conditions.subprocess.run
        run_hard_conditions.subprocess.run = fake_run
        try:
            for frames in (40, 300):
                calls.clear()
                args = argparse.Namespace(reuse=True, teach_frames=frames, set=[], after_frames=20)
                with self.assertRaises(RuntimeError):
                    run_hard_conditions.run_one(1, 'none', self.work, args, RUNNER)
                self.assertEqual(os.path.basename(calls[0][1]) == 'generate_route', frames == 300, frames)
        finally:
            run_hard_conditions.subprocess.run = real_run

    def test_an_output_json_in_a_missing_folder_is_refused_before_the_runs(self):
        self.assertIn('its folder does not exist',
                      self.refused('--output-json', os.path.join(self.work, 'nodir', 'x.json')))

    def test_a_set_without_a_value_is_refused(self):
        self.assertIn("--set takes NAME=VALUE, got 'min_texture_ratio'", self.refused('--set', 'min_texture_ratio'))


if __name__ == '__main__':
    unittest.main()
