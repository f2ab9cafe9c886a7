"""localize_offline, the built C++ runner: its CSV interface on a folder pair, and bad input (missing paths,
empty folders, unreadable images, unwritable output, bad options) giving a message and a non-zero exit."""

import csv
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np

try:
    import cv2
except ImportError:  # pragma: no cover - depends on the machine
    cv2 = None


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import built_executable  # noqa: E402

RUNNER = built_executable('localize_offline')


def bag_header_field(content, name):
    """A u64 field of a rosbag 2.0 file's bag header record (the record right after '#ROSBAG V2.0\\n')."""
    assert content[:13] == b'#ROSBAG V2.0\n'
    header_length = int.from_bytes(content[13:17], 'little')
    header, at = content[17:17 + header_length], 0
    while at < len(header):
        field_length = int.from_bytes(header[at:at + 4], 'little')
        key, _, value = header[at + 4:at + 4 + field_length].partition(b'=')
        if key == name:
            return int.from_bytes(value, 'little')
        at += 4 + field_length
    raise KeyError(name)


@unittest.skipIf(RUNNER is None or cv2 is None,
                 'localize_offline not built in a sourced workspace (source devel/setup.bash), or no cv2')
class LocalizeOfflineTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix='localize_offline_test_')
        # A route of 40 frames: a random texture seen through a window sliding 16 px per frame (8 px of
        # the 64 px preprocessed image, beyond the +-4 px shift search), so neighbours overlap but no
        # keyframe explains its neighbour by a shift.
        rng = np.random.RandomState(5)
        world = cv2.resize(rng.randint(0, 256, (32, 160)).astype(np.uint8), (800, 96), interpolation=cv2.INTER_CUBIC)
        cls.map_dir = cls.folder('map', [world[:, 16 * i:16 * i + 128] for i in range(40)])
        cls.empty_dir = cls.folder('empty', [])
        cls.bad_dir = os.path.join(cls.tmp, 'bad')
        os.makedirs(cls.bad_dir)
        with open(os.path.join(cls.bad_dir, 'a.png'), 'wb') as f:
            f.write(b'not a png')

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    @classmethod
    def folder(cls, name, images):
        path = os.path.join(cls.tmp, name)
        os.makedirs(path)
        for i, image in enumerate(images):
            cv2.imwrite(os.path.join(path, '%05d.png' % i), image)
        return path

    def run_runner(self, *args):
        return subprocess.run([RUNNER, '--quiet'] + list(args), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              universal_newlines=True, timeout=120)

    def test_same_route_matches_every_frame_after_initialization(self):
        output = os.path.join(self.tmp, 'same.csv')
        result = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output)
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(output) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), 40)
        self.assertEqual(list(rows[0].keys())[:6],
                         ['query_index', 'keyframe', 'confidence', 'shift_px', 'homing_angle_rad', 'status'])
        self.assertEqual([int(r['query_index']) for r in rows], list(range(40)))
        tracked = [r for r in rows if r['status'] in ('tracking', 'end_of_route')]
        self.assertGreaterEqual(len(tracked), 30)
        for r in tracked:
            self.assertEqual(int(r['keyframe']), int(r['query_index']))
            self.assertLess(abs(float(r['shift_px'])), 0.25)
        for r in rows:
            self.assertTrue(0.0 <= float(r['confidence']) <= 1.0)

    def test_progress_goes_to_stderr_and_the_results_to_stdout(self):
        # Issue 33: it printed only at the end. With --progress lines (forced: a short run in a log stays
        # quiet by default) a line at every 10 % of each stage on stderr; the CSV on stdout is untouched.
        result = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', '/dev/stdout',
                                 '--progress', 'lines')
        self.assertEqual(result.returncode, 0, result.stderr)
        rows = list(csv.DictReader(result.stdout.splitlines()))
        self.assertEqual([int(r['query_index']) for r in rows], list(range(40)))
        for stage in ('loading the map', 'loading the queries', 'localizing'):
            prefix = 'localize_offline: %s ' % stage
            lines = [line.split(',')[0] for line in result.stderr.splitlines() if line.startswith(prefix)]
            self.assertEqual(lines, ['%s%d/40 (%d %%)' % (prefix, 4 * k, 10 * k) for k in range(1, 11)])
        quiet = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', '/dev/stdout')
        self.assertNotIn('%', quiet.stderr)  # --quiet (run_runner's) turns it off
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', '/dev/null',
                                         '--progress', 'loud'), "--progress takes auto, bar, lines or off, got 'loud'")

    def test_saved_map_gives_the_same_results_as_its_images(self):
        # --save-map writes the loaded map in the recorder's format; run again on that file, every row
        # must be the same as with the folder of images (the file holds the preprocessed keyframes).
        map_file, from_images = self.save_map('saved')
        from_file = os.path.join(self.tmp, 'from_file.csv')
        self.assertGreater(os.path.getsize(map_file), 40 * 64 * 32)
        result = self.run_runner('--map', map_file, '--query', self.map_dir, '--output', from_file)
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(from_images) as a, open(from_file) as b:
            self.assertEqual(a.read(), b.read())
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', from_file,
                                         '--save-map', '/no/such/dir/saved.map'), '--save-map', '/no/such/dir')
        # Parameters the map cannot take are refused before the map file is written (it was written, and
        # then the run failed).
        refused_map = os.path.join(self.tmp, 'refused.map')
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', from_file,
                                         '--save-map', refused_map, '--set', 'start_keyframe=40'),
                         'start_keyframe must be below the map')
        self.assertFalse(os.path.exists(refused_map))

    def save_map(self, name, *options):
        """Runs the map folder against itself with --save-map; returns (map file, results csv)."""
        map_file = os.path.join(self.tmp, name + '.map')
        output = os.path.join(self.tmp, name + '.csv')
        result = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output,
                                 '--save-map', map_file, *options)
        self.assertEqual(result.returncode, 0, result.stderr)
        return map_file, output

    def assertFails(self, result, *fragments):
        self.assertNotEqual(result.returncode, 0)
        self.assertGreater(result.returncode, 0, 'killed by a signal: %s' % result.stderr)
        for fragment in fragments:
            self.assertIn(fragment, result.stderr)

    def test_missing_paths(self):
        output = os.path.join(self.tmp, 'missing.csv')
        self.assertFails(self.run_runner('--map', '/no/such/map', '--query', self.map_dir, '--output', output),
                         '/no/such/map')
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', '/no/such/query', '--output', output),
                         '/no/such/query')
        self.assertFalse(os.path.exists(output))

    def test_check_params_answers_as_a_run_would_without_any_input(self):
        params = os.path.join(self.tmp, 'check_params.yaml')
        with open(params, 'w') as f:
            f.write('localizer:\n  max_step: 3\n')
        ok = self.run_runner('--check-params', '--params', params, '--method', 'seqslam', '--set', 'ring_buffer_rows=20')
        self.assertEqual(ok.returncode, 0, ok.stderr)
        self.assertIn('the parameters are valid', ok.stdout)
        # each refused as the run refuses it: a value out of range, an unknown name, a bad method
        for args, reason in ((['--set', 'max_step=0'], "parameter 'max_step' must be in 1 .. 16"),
                             (['--set', 'no_such_parameter=1'], "unknown parameter 'no_such_parameter'"),
                             (['--method', 'hmm'], '--method must be dtw or seqslam'),
                             (['--params', '/no/such/params.yaml'], '/no/such/params.yaml'),
                             (['--set', 'max_shift_px=40'], 'max_shift_px must be below half the image width (at most 31 for 64 px)'),
                             (['--set', 'sky_fraction=0.9', '--set', 'shift_bands=4'],
                              'shift_bands must be at most the compared rows (3), got 4')):
            check = self.run_runner('--check-params', *args)
            self.assertFails(check, reason)
            self.assertEqual(check.returncode, 2, check.stderr)
            output = os.path.join(self.tmp, 'check_params.csv')
            self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output, *args),
                             reason)
            self.assertFalse(os.path.exists(output))
        # a params file a run corrects is taken, and said to be corrected, not called valid
        with open(params, 'w') as f:
            f.write('localizer:\n  max_step: 99\n  no_such_parameter: 1\n')
        corrected = self.run_runner('--check-params', '--params', params)
        self.assertEqual(corrected.returncode, 0, corrected.stderr)
        self.assertIn('max_step 99 is outside 1 .. 16', corrected.stderr)
        self.assertIn('with the 2 warnings above about %s (values corrected, entries skipped)' % params,
                      corrected.stdout)
        self.assertNotIn('valid', corrected.stdout)
        # an even filter_window, corrected as the preprocessor nodelet corrects it from the same file (refused
        # before: the robot's params file could not be checked or used offline)
        with open(params, 'w') as f:
            f.write('preprocessor:\n  filter_window: 8\n')
        corrected = self.run_runner('--check-params', '--params', params)
        self.assertEqual(corrected.returncode, 0, corrected.stderr)
        self.assertIn('%s: filter_window 8 is even; using 9' % params, corrected.stderr)
        self.assertIn('with the 1 warning above about', corrected.stdout)
        # follow.launch's params_file: the follower's and the recorder's sections are checked as their nodelets
        # read them (they were skipped), a name under another nodelet's section is named; their own settings
        # (autostart, control_rate) are not refused
        with open(params, 'w') as f:
            f.write('map_recorder:\n  autostart: true\n  every_nth: 2\nroute_follower:\n  control_rate: 20\n'
                    '  homing_gain: 99\n  speed_factr: 0.5\n  every_nth: 2\n')
        checked = self.run_runner('--check-params', '--params', params)
        self.assertEqual(checked.returncode, 0, checked.stderr)
        self.assertIn('%s:6: homing_gain 99 is outside 0 .. ' % params, checked.stderr)
        self.assertIn("%s:7: unknown parameter 'speed_factr' refused (did you mean speed_factor?)" % params,
                      checked.stderr)
        self.assertIn("%s:8: 'every_nth' is the map_recorder's parameter but is under route_follower:" % params,
                      checked.stderr)
        self.assertIn('with the 3 warnings above', checked.stdout)
        # it reads no input: given one, it says so rather than ignoring it
        self.assertFails(self.run_runner('--check-params', '--map', self.map_dir), 'reads no map, query or output')

    def test_empty_folder(self):
        self.assertFails(self.run_runner('--map', self.empty_dir, '--query', self.map_dir, '--output',
                                         os.path.join(self.tmp, 'empty.csv')), self.empty_dir)

    def test_unreadable_image(self):
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.bad_dir, '--output',
                                         os.path.join(self.tmp, 'bad.csv')), 'a.png')

    def test_a_gap_in_a_bags_stamps_is_frames_missed(self):
        # The route's frames 0..39 stamped 1 s apart, frames 20..27 missing (the camera dropped out while
        # the robot drove on): one row per message, the gap named in the summary, and the frames after it
        # answered where they are.
        from sensor_msgs.msg import Image
        messages = [m for m in self.frames(0, 40) if not 1020 <= m.header.stamp.secs < 1028]
        self.assertIsInstance(messages[0], Image)
        bag = self.write_bag('gap.bag', messages)
        output = os.path.join(self.tmp, 'gap.csv')
        result = self.run_runner('--map', self.map_dir, '--query', bag, '--output', output)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn('32 queries, 1 gaps in the stamps (8 frames missed)', result.stderr)
        with open(output) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), 32)
        after = rows[20:]  # frames 28..39
        self.assertEqual([int(r['keyframe']) for r in after], list(range(28, 40)))
        self.assertTrue(all(r['status'] in ('tracking', 'end_of_route') for r in after), after)
        # Told not to fill gaps in (a camera triggered by distance), it still names the gap.
        result = self.run_runner('--map', self.map_dir, '--query', bag, '--output', output,
                                 '--set', 'fill_frame_gaps=false')
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn('(8 frames missed, not filled in: fill_frame_gaps is off)', result.stderr)
        # The camera dropped out for 7 frames while the robot stood at frame 19: after the gap, the view
        # before it again, then frames 20..39. Nothing is filled in, and the frames after it are right.
        still = self.write_bag('still.bag', messages[:20] + [self.restamped(m, 1027 + i)
                                                             for i, m in enumerate(messages[19:20] + self.frames(20, 40))])
        result = self.run_runner('--map', self.map_dir, '--query', still, '--output', output)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn('41 queries, 1 gaps in the stamps (7 frames missed; 1 with the same view before and after, '
                      'not filled in)', result.stderr)
        with open(output) as f:
            self.assertEqual([int(r['keyframe']) for r in list(csv.DictReader(f))[20:]], list(range(19, 40)))
        # With a window of 5 rows the gap leaves nothing to join up with: the search starts over.
        result = self.run_runner('--map', self.map_dir, '--query', bag, '--output', output,
                                 '--set', 'ring_buffer_rows=5')
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn('1 gaps in the stamps (0 frames missed; 1 longer than the window, searched again)',
                      result.stderr)
        with open(output) as f:
            self.assertEqual(list(csv.DictReader(f))[20]['status'], 'lost')

    def frames(self, first, last):
        """The route's frames [first, last) as mono8 image messages, frame i stamped 1000 + i s."""
        import rospy
        messages = []
        for i in range(first, last):
            image = cv2.imread(os.path.join(self.map_dir, '%05d.png' % i), cv2.IMREAD_GRAYSCALE)
            msg = self.image('mono8', image.shape[1], image.shape[0], image.tobytes(), image.shape[1])
            msg.header.stamp = rospy.Time(1000 + i)
            messages.append(msg)
        return messages

    @staticmethod
    def restamped(msg, seconds):
        """A copy of the image message `msg` stamped `seconds`."""
        import copy
        import rospy
        other = copy.deepcopy(msg)
        other.header.stamp = rospy.Time(seconds)
        return other

    def write_bag(self, name, images, seconds=None):
        """A bag with the image messages `images` on /cam, at bag times 100, 101, ... (header
        stamps `seconds` if given: a recording of a looping `rosbag play`)."""
        import rosbag
        import rospy
        path = os.path.join(self.tmp, name)
        with rosbag.Bag(path, 'w') as bag:
            for i, msg in enumerate(images):
                if seconds is not None:
                    msg.header.stamp = rospy.Time(seconds[i])
                bag.write('/cam', msg, rospy.Time(100 + i))
        return path

    @staticmethod
    def image(encoding, width, height, data, step, bigendian=0):
        from sensor_msgs.msg import Image
        msg = Image()
        msg.encoding, msg.width, msg.height, msg.step, msg.data, msg.is_bigendian = (
            encoding, width, height, step, bytes(data), bigendian)
        return msg

    def test_bad_bag_messages_are_named_by_bag_topic_and_position(self):
        # Each bag: two good frames, then the bad one at position 2; the error names all three.
        good = self.image('mono8', 64, 32, bytes(range(256)) * 8, 64)
        nan = np.full((32, 64), 0.5, np.float32)
        nan[5, 7] = np.nan
        cases = {
            'step.bag': (self.image('mono8', 64, 32, bytes(64 * 32), 32), 'step 32'),
            'short.bag': (self.image('mono8', 64, 32, bytes(64 * 32 - 1), 64), '2047 bytes of data'),
            'big_endian.bag': (self.image('mono16', 64, 32, bytes(64 * 32 * 2), 128, bigendian=1),
                               "big-endian 'mono16'"),
            'nan.bag': (self.image('32FC1', 64, 32, nan.tobytes(), 256), 'NaN'),
            'yuv.bag': (self.image('yuv422', 64, 32, bytes(64 * 32 * 2), 128), "unsupported encoding 'yuv422'"),
        }
        for name, (bad, words) in cases.items():
            bag = self.write_bag(name, [good, good, bad])
            self.assertFails(self.run_runner('--map', self.map_dir, '--query', bag, '--output',
                                             os.path.join(self.tmp, 'bad_bag.csv')),
                             "'%s', topic '/cam', message 2 (bag time 102" % bag, words)

    def test_a_bag_of_compressed_images_localizes_as_its_raw_frames_do(self):
        # A camera bag recorded through image_transport's compressed plugin (sensor_msgs/CompressedImage) was
        # "0 sensor_msgs/Image topics". PNG is lossless: the same frames, so the same answers as the raw bag,
        # stamps included; undecodable data is named by bag, topic and position.
        from sensor_msgs.msg import CompressedImage
        frames = [cv2.imread(os.path.join(self.map_dir, name), cv2.IMREAD_GRAYSCALE)
                  for name in sorted(os.listdir(self.map_dir))]
        raw = self.write_bag('raw.bag', [self.image('mono8', f.shape[1], f.shape[0], f.tobytes(), f.shape[1])
                                         for f in frames], seconds=[50 + 0.1 * i for i in range(len(frames))])

        def compressed(data, fmt):
            msg = CompressedImage()
            msg.format, msg.data = fmt, bytes(data)
            return msg
        png = self.write_bag('png.bag', [compressed(cv2.imencode('.png', f)[1].tobytes(), 'mono8; png compressed ')
                                         for f in frames], seconds=[50 + 0.1 * i for i in range(len(frames))])
        outputs = []
        for bag in (raw, png):
            outputs.append(bag + '.csv')
            result = self.run_runner('--map', self.map_dir, '--query', bag, '--output', outputs[-1])
            self.assertEqual(result.returncode, 0, result.stderr)
        with open(outputs[0]) as f:
            raw_rows = f.read()
        with open(outputs[1]) as f:
            self.assertEqual(f.read(), raw_rows)
        self.assertEqual(len(raw_rows.splitlines()), len(frames) + 1)
        # A bag with no message at all (what `rosbag reindex` keeps of a map cut in its only chunk) says so,
        # rather than "0 image topics (none); choose one with --topic".
        empty = self.write_bag('empty.bag', [])
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', empty, '--output',
                                         os.path.join(self.tmp, 'empty.csv')), "bag '%s' holds no messages" % empty)
        broken = self.write_bag('broken.bag', [compressed(cv2.imencode('.png', frames[0])[1].tobytes(), 'png'),
                                               compressed(b'not an image', 'jpeg')])
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', broken, '--output',
                                         os.path.join(self.tmp, 'broken.csv')),
                         "'%s', topic '/cam', message 1 (bag time 101" % broken,
                         "12 bytes of format 'jpeg' do not decode as an image")

    def run_warned_at_message_1(self, name, frames):
        """localize_offline on a bag of these query frames, whose frames 1 and 2 are usable but worth a
        warning: the run goes on, the warning names message 1 and not message 2 (the rest are counted)."""
        bag = self.write_bag(name, frames)
        result = self.run_runner('--map', self.map_dir, '--query', bag, '--output', os.path.join(self.tmp, name + '.csv'))
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn("'%s', topic '/cam', message 1 (bag time 101" % bag, result.stderr)
        self.assertNotIn('message 2 (', result.stderr)
        return result

    def test_float_frames_outside_zero_to_one_are_clipped_and_said_once(self):
        # Three 32FC1 frames, two of them in kelvin (250..310): the run goes on, the first such frame is
        # named, the count given at the end.
        kelvin = np.linspace(250.0, 310.0, 64 * 32, dtype=np.float32).reshape(32, 64)
        unit = np.linspace(0.0, 1.0, 64 * 32, dtype=np.float32).reshape(32, 64)
        result = self.run_warned_at_message_1(
            'kelvin.bag', [self.image('32FC1', 64, 32, f.tobytes(), 256) for f in (unit, kelvin, kelvin)])
        self.assertIn('32FC1 values from 250 to 310, outside the [0, 1] read as intensity: clipped', result.stderr)
        self.assertIn('2 of 3 32FC1 frames had values outside [0, 1], clipped', result.stderr)

    def test_frames_smaller_than_the_output_are_enlarged_and_said_once(self):
        # A bag: a 64 x 32 frame, then two 1 x 1 ones; a folder: one 32 x 16 image among 64 x 32 ones.
        # The runs go on (the frames are usable, if poor); the first such frame is named, the count given.
        full = self.image('mono8', 64, 32, bytes(range(256)) * 8, 64)
        dot = self.image('mono8', 1, 1, b'\x80', 1)
        result = self.run_warned_at_message_1('dots.bag', [full, dot, dot])
        self.assertIn('a 1x1 image smaller than the 64x32 output: enlarged', result.stderr)
        self.assertIn('2 of 3 frames were smaller than the output, enlarged', result.stderr)
        # Two sizes in one query: said once, with the count (one camera's frames have one size).
        self.assertEqual(result.stderr.count('are not the size of the first'), 1, result.stderr)
        self.assertIn("warning: 2 of the 3 frames of '", result.stderr)
        self.assertIn("are not the size of the first (message 0, 64x32), e.g. message 1, 1x1: each is resized to the "
                      "output, but one camera's frames have one size (two cameras mixed?)", result.stderr)
        ramp = np.tile(np.arange(0, 256, 4, dtype=np.uint8), (32, 1))
        folder = self.folder('small', [ramp, ramp, cv2.resize(ramp, (32, 16)), ramp])
        result = self.run_runner('--map', self.map_dir, '--query', folder, '--output', os.path.join(self.tmp, 's.csv'))
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn("'%s' is a 32x16 image smaller than the 64x32 output" % os.path.join(folder, '00002.png'),
                      result.stderr)
        self.assertIn('smaller than the output: 1 of the 4 images', result.stderr)
        self.assertIn("warning: 1 of the 4 images are not the size of the first ('%s', 64x32), e.g. '%s', 32x16"
                      % (os.path.join(folder, '00000.png'), os.path.join(folder, '00002.png')), result.stderr)
        # The map's own 128 x 96 images are not, and have one size.
        self.assertNotIn(self.map_dir, result.stderr)
        self.assertEqual(result.stderr.count('are not the size of the first'), 1, result.stderr)

    def test_a_cut_short_or_foreign_file_is_named_for_what_it_is(self):
        good = self.image('mono8', 64, 32, bytes(range(256)) * 8, 64)
        bag = self.write_bag('whole.bag', [good] * 20)
        with open(bag, 'rb') as f:
            content = f.read()
        cut = os.path.join(self.tmp, 'cut.bag')
        with open(cut, 'wb') as f:
            f.write(content[:len(content) // 2])
        foreign = os.path.join(self.tmp, 'notes.txt')
        with open(foreign, 'w') as f:
            f.write('not a bag at all')
        output = os.path.join(self.tmp, 'cut.csv')
        self.assertFails(self.run_runner('--map', cut, '--query', self.map_dir, '--output', output),
                         'probably cut short', 'rosbag reindex %s' % cut)
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', foreign, '--output', output),
                         "'%s' is not a bag or map file" % foreign)
        # A file that ends inside the 13-byte bag header holds nothing to reindex; a bag of format 1.2
        # is a bag, but not one rosbag 2.0 reads.
        stub = os.path.join(self.tmp, 'stub.bag')
        with open(stub, 'wb') as f:
            f.write(content[:7])
        header_cut = os.path.join(self.tmp, 'header_cut.bag')  # '#ROSBAG V2.0' without its newline
        with open(header_cut, 'wb') as f:
            f.write(content[:12])
        self.assertFails(self.run_runner('--map', header_cut, '--query', self.map_dir, '--output', output),
                         "'%s' is cut short inside the bag header (12 bytes)" % header_cut)
        old = os.path.join(self.tmp, 'old.bag')
        with open(old, 'wb') as f:
            f.write(b'#ROSBAG V1.2\n' + content[13:])
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', stub, '--output', output),
                         "'%s' is cut short inside the bag header (7 bytes)" % stub)
        self.assertFails(self.run_runner('--map', old, '--query', self.map_dir, '--output', output),
                         "'%s' is a rosbag of another format version than 2.0" % old)

    def test_a_map_file_without_its_index_is_read_as_a_map(self):
        # rosbag reads a bag from the index at its end; a map file cut off at the index (copied or written
        # while the disk filled up) holds every keyframe, and the map reader walks its records. The run
        # on it must give every row as on the whole file. Cut inside a keyframe, the file names the cut.
        map_file, whole = self.save_map('indexed')
        with open(map_file, 'rb') as f:
            content = f.read()
        index_pos = bag_header_field(content, b'index_pos')
        self.assertGreater(index_pos, 40 * 64 * 32)
        self.assertLess(index_pos, len(content))
        unindexed = os.path.join(self.tmp, 'unindexed.map')
        with open(unindexed, 'wb') as f:
            f.write(content[:index_pos])
        output = os.path.join(self.tmp, 'unindexed.csv')
        result = self.run_runner('--map', unindexed, '--query', self.map_dir, '--output', output)
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(whole) as a, open(output) as b:
            self.assertEqual(a.read(), b.read())
        cut = os.path.join(self.tmp, 'cut.map')
        with open(cut, 'wb') as f:
            f.write(content[:index_pos // 2])
        self.assertFails(self.run_runner('--map', cut, '--query', self.map_dir, '--output', output),
                         'probably cut short', 'rosbag reindex %s' % cut)

    def test_an_output_inside_an_input_folder_is_refused_and_the_folder_kept(self):
        # Every image file of an input folder is read: a results file named like a frame replaced it
        # (and any file written there is read as a frame next time). Refused, with the folder as it was.
        inputs = os.path.join(self.tmp, 'inputs_kept')
        shutil.copytree(self.map_dir, inputs)
        before = {n: open(os.path.join(inputs, n), 'rb').read() for n in os.listdir(inputs)}
        results = os.path.join(self.tmp, 'inside.csv')
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', inputs, '--output',
                                         os.path.join(inputs, '00003.png')),
                         "--output '%s' is inside the --query folder '%s'" % (os.path.join(inputs, '00003.png'),
                                                                                inputs))
        self.assertFails(self.run_runner('--map', inputs, '--query', self.map_dir, '--output', results,
                                         '--save-map', os.path.join(inputs, 'route.map')),
                         "is inside the --map folder '%s'" % inputs)
        self.assertEqual({n: open(os.path.join(inputs, n), 'rb').read() for n in os.listdir(inputs)}, before)
        self.assertFalse(os.path.exists(results))
        # Beside the folder is fine.
        result = self.run_runner('--map', self.map_dir, '--query', inputs, '--output', results)
        self.assertEqual(result.returncode, 0, result.stderr)

    def test_a_map_file_as_the_query_gives_the_results_of_its_images(self):
        # A map file's keyframes are preprocessed already: as the query they are used as stored (they were
        # preprocessed a second time), and only when made as the run's frames must be.
        map_file, from_images = self.save_map('as_query')
        from_file = os.path.join(self.tmp, 'as_query_file.csv')
        result = self.run_runner('--map', self.map_dir, '--query', map_file, '--output', from_file)
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(from_images) as a, open(from_file) as b:
            self.assertEqual(a.read(), b.read())
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', map_file, '--output', from_file,
                                         '--set', 'normalization_strength=0.2'),
                         "the map file '%s' was made with other preprocessing parameters" % map_file,
                         'normalization_strength: 0.1 vs 0.2')

    def test_an_image_bag_is_opened_once(self):
        # As the map or as the query, a bag was opened twice: once to tell whether it is a map file, then again
        # to read its images. Counted with strace: the files opened, and how often.
        import re
        strace = shutil.which('strace')
        if strace is None:
            self.skipTest('needs strace')
        map_bag = self.write_bag('once_map.bag', self.frames(0, 40))
        query_bag = self.write_bag('once_query.bag', self.frames(0, 40))
        trace = os.path.join(self.tmp, 'once.trace')
        output = os.path.join(self.tmp, 'once.csv')
        result = subprocess.run([strace, '-f', '-e', 'trace=open,openat', '-o', trace, RUNNER, '--quiet', '--map',
                                 map_bag, '--query', query_bag, '--output', output], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, universal_newlines=True, timeout=120)
        if result.returncode != 0 and 'ptrace' in result.stderr:
            self.skipTest('strace cannot trace here: %s' % result.stderr.strip()[:200])
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(output) as f:
            self.assertEqual(len(list(csv.DictReader(f))), 40)
        with open(trace) as f:
            opened = f.read()
        for bag in (map_bag, query_bag):
            self.assertEqual(len(re.findall(r'open(?:at)?\(.*"%s", .*\) = \d+' % re.escape(bag), opened)), 1, bag)

    def test_a_map_file_that_lost_its_parameters_is_refused_not_read_as_images(self):
        # A map file without its 'preprocessing' topic (a `rosbag filter`, a damaged index) was read as an
        # image bag: its keyframes preprocessed again, the results silently different.
        import rosbag
        map_file, _ = self.save_map('lost_params')
        stripped = os.path.join(self.tmp, 'lost_params_stripped.map')
        with rosbag.Bag(map_file) as source, rosbag.Bag(stripped, 'w') as target:
            for topic, msg, stamp in source.read_messages(raw=True):
                if topic != 'preprocessing':
                    target.write(topic, msg, stamp, raw=True)
        output = os.path.join(self.tmp, 'lost_params.csv')
        for role in ('--map', '--query'):
            other = '--query' if role == '--map' else '--map'
            self.assertFails(self.run_runner(role, stripped, other, self.map_dir, '--output', output),
                             "map file '%s' holds no preprocessing parameters" % stripped)

    def test_a_damaged_message_is_named_by_bag_topic_and_position(self):
        # rosbag's own words ("Buffer Overrun") named neither the file nor the message. Message 2's data
        # length is made impossible: messages 0 and 1 read well.
        good = self.image('mono8', 64, 32, bytes(range(256)) * 8, 64)
        bag = self.write_bag('damaged.bag', [good, good, good])
        with open(bag, 'rb') as f:
            content = bytearray(f.read())
        pattern = b'mono8\x00' + (64).to_bytes(4, 'little') + (2048).to_bytes(4, 'little')
        at = -1
        for _ in range(3):
            at = content.index(pattern, at + 1)
        content[at + 10:at + 14] = (0x7fffffff).to_bytes(4, 'little')
        with open(bag, 'wb') as f:
            f.write(content)
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', bag, '--output',
                                         os.path.join(self.tmp, 'damaged.csv')),
                         "bag '%s' is damaged at message 2 of topic '/cam' (rosbag says: " % bag,
                         'the 2 messages before it read well')

    def test_a_map_bag_whose_stamps_go_back_is_warned_of(self):
        # A map bag that holds the drive twice (recorded from a looping `rosbag play`: header stamps 100-104,
        # then 100-104 again): every image is still a keyframe, but each place now has a look-alike; it was
        # loaded without a word.
        frames = [self.image('mono8', 64, 32, bytes([(17 * i + 3 * j) % 256 for j in range(64 * 32)]), 64)
                  for i in range(5)]
        once = self.write_bag('drive_once.bag', frames, [100, 101, 102, 103, 104])
        twice = self.write_bag('drive_twice.bag', frames + frames, [100, 101, 102, 103, 104] * 2)
        output = os.path.join(self.tmp, 'twice.csv')
        result = self.run_runner('--map', twice, '--query', self.map_dir, '--output', output)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn("warning: the map bag '%s': its stamps go back 1 time(s), first at message 5" % twice,
                      result.stderr)
        self.assertIn('localize_offline: 10 keyframes', result.stderr)
        result = self.run_runner('--map', once, '--query', self.map_dir, '--output', output)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertNotIn('go back', result.stderr)

    def test_unwritable_output(self):
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output',
                                         '/no/such/dir/out.csv'), '/no/such/dir/out.csv')

    def test_a_failed_run_leaves_earlier_files_as_they_were(self):
        # Results are written beside the output and renamed over it at the end, parameters are checked
        # before anything is written, and no output may name an input: a results file written over the
        # query bag, or truncated by a run that then refused its parameters, was lost.
        map_file, keep = self.save_map('keep')
        with open(keep) as f:
            results = f.read()
        with open(map_file, 'rb') as f:
            map_bytes = f.read()
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', keep,
                                         '--set', 'contrast_clamp=0'), 'contrast_clamp')
        self.assertFails(self.run_runner('--map', map_file, '--query', self.map_dir, '--output', map_file),
                         '--output', '--map')
        self.assertFails(self.run_runner('--map', map_file, '--query', self.map_dir, '--output', keep,
                                         '--save-map', map_file), '--save-map', '--map')
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', keep,
                                         '--save-map', keep), '--save-map', '--output')
        if os.path.exists('/dev/full'):  # a full disk: the rows did not reach the file
            self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output',
                                             '/dev/full'), '/dev/full')
        with open(keep) as f:
            self.assertEqual(f.read(), results)
        with open(map_file, 'rb') as f:
            self.assertEqual(f.read(), map_bytes)
        self.assertEqual([n for n in os.listdir(self.tmp) if '.partial.' in n], [])

    def test_reads_the_launch_files_params_file(self):
        # The params_file given to teach.launch and repeat.launch: its localizer: section applies, its
        # map_recorder: section is not used, a misspelt name is refused with a warning naming file and line.
        params = os.path.join(self.tmp, 'shared_params.yaml')
        with open(params, 'w') as f:
            f.write('preprocessor:\n  normalization_strength: 0.1\nmap_recorder:\n  every_nth: 3\n'
                    'localizer:\n  start_keyframe: -1  # the start unknown: a global search\n'
                    '  min_init_frames: 30  # no answer is confirmed before 30 rows\n')
        output = os.path.join(self.tmp, 'shared_params.csv')
        result = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output,
                                 '--params', params)
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(output) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([r['status'] for r in rows[:29]], ['initializing'] * 29)
        self.assertIn('tracking', [r['status'] for r in rows[29:]])
        with open(params, 'a') as f:
            f.write('  ring_bufer_rows: 10\n')
        result = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output, '--params', params)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn("shared_params.yaml:8: unknown parameter 'ring_bufer_rows' refused (did you mean "
                      "ring_buffer_rows?)", result.stderr)

    def test_one_bad_value_in_the_params_file_is_refused_by_name_and_the_good_ones_used(self):
        # Issue 33: "method: DTW" rejected the whole file, and the defaults were used instead of the good
        # values. min_init_frames: 30 shows that the good values are used (no answer before row 30), and
        # sky_fraction: -0.5 is used as its nearest working value, 0.
        params = os.path.join(self.tmp, 'one_bad.yaml')
        with open(params, 'w') as f:
            f.write('localizer:\n  start_keyframe: -1\n  method: DTW\n  min_init_frames: 30\n'
                    'preprocessor:\n  sky_fraction: -0.5\n')
        output = os.path.join(self.tmp, 'one_bad.csv')
        result = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output,
                                 '--params', params)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn("one_bad.yaml:3: method 'DTW' is not one of dtw | seqslam; keeping dtw", result.stderr)
        self.assertIn('one_bad.yaml:6: sky_fraction -0.5 is outside 0 .. 0.95; using 0', result.stderr)
        with open(output) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([r['status'] for r in rows[:29]], ['initializing'] * 29)
        self.assertIn('tracking', [r['status'] for r in rows[29:]])

    def test_help_lists_the_user_tier_and_help_advanced_every_parameter(self):
        # issue 30, item 5: --help shows the parameters a user sets for the robot and route, with their
        # default, range and meaning, and says how many advanced ones there are and how to list them.
        result = self.run_runner('--help')
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn('    ring_buffer_rows = 30  (3 .. 1000 frames)\n'
                      '        K: frames in the sequence window', result.stdout)
        self.assertIn('    normalization = divisive  (patch | divisive | none)\n', result.stdout)
        self.assertNotIn('skip_penalty', result.stdout)
        self.assertIn('  and 47 advanced parameters, not shown', result.stdout)
        self.assertIn('localize_offline --help-advanced lists them', result.stdout)

        def listed(stdout):
            return [line.split(' = ')[0].strip() for line in stdout.splitlines()
                    if line.startswith('    ') and not line.startswith('        ') and ' = ' in line]
        user = listed(result.stdout)
        self.assertEqual(len(user), 20)  # 6 of the preprocessor, 14 of the localizer (test_core, ParameterTiers)
        for name in ('max_step', 'max_shift_px', 'contrast_window', 'output_width', 'start_keyframe'):
            self.assertIn(name, user)
        for name in ('min_texture_ratio', 'seqslam_sequence_length', 'parallel', 'output_gain'):
            self.assertNotIn(name, user)
        # With --help-advanced every name the parameter file takes is listed (once), with a default and a
        # line of meaning: the user tier's and the 46 others.
        result = self.run_runner('--help-advanced')
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn('    skip_penalty = 0.85  (0 .. 10 cost)\n', result.stdout)
        self.assertIn('  localizer, advanced:\n', result.stdout)
        self.assertNotIn('not shown', result.stdout)
        every = listed(result.stdout)
        self.assertEqual(len(every), len(set(every)))
        self.assertEqual(len(every), 67)
        self.assertTrue(set(user) < set(every))
        for name in ('max_step', 'min_texture_ratio', 'output_width', 'seqslam_sequence_length', 'parallel',
                     'posterior_cost_scale'):
            self.assertIn(name, every)

    def test_a_removed_parameter_in_the_params_file_is_named_with_the_value_it_is_fixed_at(self):
        # contrast_min_std was a parameter until it became a constant (0.01, its default): a params file
        # written for the earlier version still runs, and says what became of it.
        params = os.path.join(self.tmp, 'removed.yaml')
        with open(params, 'w') as f:
            f.write('localizer:\n  start_keyframe: -1\n  contrast_min_std: 0.05\n  min_init_frames: 30\n')
        output = os.path.join(self.tmp, 'removed.csv')
        result = self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output,
                                 '--params', params)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn('removed.yaml:3: contrast_min_std was removed in this version; it is now fixed at 0.01 (',
                      result.stderr)
        with open(output) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([r['status'] for r in rows[:29]], ['initializing'] * 29)  # min_init_frames: 30 used
        self.assertIn('tracking', [r['status'] for r in rows[29:]])

    def test_preprocessing_given_for_a_map_file_must_agree_with_it(self):
        # A map file's keyframes were preprocessed with its stored parameters; a query preprocessed with
        # others would be compared with them all the same. Given and equal: runs; given and different:
        # refused, naming the difference; invalid: refused before anything is loaded.
        map_file, output = self.save_map('strength', '--set', 'normalization_strength=0.2')
        result = self.run_runner('--map', map_file, '--query', self.map_dir, '--output', output,
                                 '--set', 'normalization_strength=0.2')
        self.assertEqual(result.returncode, 0, result.stderr)
        result = self.run_runner('--map', map_file, '--query', self.map_dir, '--output', output)
        self.assertEqual(result.returncode, 0, 'none given: the map\'s are used\n' + result.stderr)
        self.assertFails(self.run_runner('--map', map_file, '--query', self.map_dir, '--output', output,
                                         '--set', 'normalization_strength=0.1'),
                         'other preprocessing parameters', 'normalization_strength: 0.2 vs 0.1')
        # The same through --params (the file's preprocessor: section is compared as --set is).
        params = os.path.join(self.tmp, 'strength.yaml')
        with open(params, 'w') as f:
            f.write('preprocessor:\n  normalization_strength: 0.2\nlocalizer:\n  max_step: 2\n')
        result = self.run_runner('--map', map_file, '--query', self.map_dir, '--output', output, '--params', params)
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(params, 'w') as f:
            f.write('preprocessor:\n  normalization_strength: 0.1\n')
        self.assertFails(self.run_runner('--map', map_file, '--query', self.map_dir, '--output', output,
                                         '--params', params),
                         'other preprocessing parameters', 'normalization_strength: 0.2 vs 0.1')
        # Only names given are compared: sky_fraction 0 agrees with the map; the strength is not given.
        result = self.run_runner('--map', map_file, '--query', self.map_dir, '--output', output,
                                 '--set', 'sky_fraction=0')
        self.assertEqual(result.returncode, 0, result.stderr)
        # A field eq. 3 does not read (the map is eq. 3) makes the same bytes: it agrees.
        result = self.run_runner('--map', map_file, '--query', self.map_dir, '--output', output,
                                 '--set', 'normalization_strength=0.2', '--set', 'patch_size=4')
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertFails(self.run_runner('--map', self.map_dir, '--query', self.map_dir, '--output', output,
                                         '--set', 'output_width=0'), "'output_width' must be in 8 .. 1024 px, got 0")

    def test_bad_options(self):
        common = ['--map', self.map_dir, '--query', self.map_dir, '--output', os.path.join(self.tmp, 'o.csv')]
        self.assertFails(self.run_runner(*(common + ['--method', 'foo'])), 'foo')
        self.assertFails(self.run_runner(*(common + ['--set', 'ring_buffer_rows=0'])), 'ring_buffer_rows')
        self.assertFails(self.run_runner(*(common + ['--set', 'no_such_parameter=1'])), 'no_such_parameter')
        self.assertFails(self.run_runner('--map', self.map_dir), 'usage')
        self.assertFails(self.run_runner(*(common + ['--params', self.tmp])),
                         "cannot read parameter file '%s'" % self.tmp)


if __name__ == '__main__':
    unittest.main()
