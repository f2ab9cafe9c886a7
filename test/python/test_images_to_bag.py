"""scripts/images_to_bag: shifting, frame selection, and a bag written and read back."""

import contextlib
import io
import os
import shutil
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import load, ros_python_available

images_to_bag = load("images_to_bag")


class ShiftTest(unittest.TestCase):
    def test_right_shift_replicates_left_edge(self):
        row = np.array([[10, 20, 30, 40, 50]], np.uint8)
        np.testing.assert_array_equal(images_to_bag.shift_image(row, 2), [[10, 10, 10, 20, 30]])

    def test_left_shift_replicates_right_edge(self):
        row = np.array([[10, 20, 30, 40, 50]], np.uint8)
        np.testing.assert_array_equal(images_to_bag.shift_image(row, -1), [[20, 30, 40, 50, 50]])

    def test_colour_image_and_no_wrap(self):
        image = np.zeros((2, 4, 3), np.uint8)
        image[:, 3] = (1, 2, 3)       # rightmost column
        shifted = images_to_bag.shift_image(image, 1)
        self.assertEqual(shifted.shape, (2, 4, 3))
        np.testing.assert_array_equal(shifted[:, 0], 0)   # the right edge must not wrap to the left
        np.testing.assert_array_equal(shifted[:, 3], 0)
        self.assertEqual(images_to_bag.shift_image(image, 0).tolist(), image.tolist())


class FrameSelectionTest(unittest.TestCase):
    def test_list_with_ranges_keeps_order_and_repeats(self):
        self.assertEqual(images_to_bag.parse_frame_list("5,0,2-4,2", 10), [5, 0, 2, 3, 4, 2])

    def test_every(self):
        self.assertEqual(images_to_bag.select_frames(10, None, 3), [0, 3, 6, 9])
        self.assertEqual(images_to_bag.select_frames(10, "1-6", 2), [1, 3, 5])

    def test_bad_lists(self):
        for text in ("3,12", "a", "5-2", "", "-1"):
            with self.assertRaises(images_to_bag.InputError, msg=text):
                images_to_bag.parse_frame_list(text, 10)
        with self.assertRaises(images_to_bag.InputError):
            images_to_bag.select_frames(10, None, 0)


@unittest.skipUnless(ros_python_available(), "rosbag / sensor_msgs not importable (use /usr/bin/python3)")
class BagTest(unittest.TestCase):
    def setUp(self):
        import cv2
        self.cv2 = cv2
        self.tmp = tempfile.mkdtemp(prefix="test_images_to_bag_")
        self.folder = os.path.join(self.tmp, "images")
        os.makedirs(self.folder)
        # file names out of creation order: the bag must follow sorted file names
        for value, name in ((30, "c.png"), (10, "a.png"), (20, "b.png")):
            image = np.zeros((4, 6, 3), np.uint8)
            image[:, :, 0] = value          # blue channel (OpenCV writes BGR)
            image[:, :, 2] = value + 1      # red channel
            image[:, 5] = (200, 201, 202)   # a distinct rightmost column
            cv2.imwrite(os.path.join(self.folder, name), image)
        with open(os.path.join(self.folder, "notes.txt"), "w") as f:
            f.write("not an image")

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def read(self, path):
        import rosbag
        with rosbag.Bag(path) as bag:
            return [(topic, msg, t) for topic, msg, t in bag.read_messages()]

    def test_round_trip_rgb_with_shift(self):
        bag_path = os.path.join(self.tmp, "out.bag")
        with contextlib.redirect_stdout(io.StringIO()):
            code = images_to_bag.main([self.folder, bag_path, "--rate", "5", "--encoding", "rgb8", "--topic", "/cam/img",
                                       "--frame-id", "cam", "--start-time", "100", "--shift-px", "-1"])
        self.assertEqual(code, 0)
        messages = self.read(bag_path)
        self.assertEqual(len(messages), 3)
        for k, (topic, msg, t) in enumerate(messages):
            self.assertEqual(topic, "/cam/img")
            self.assertEqual(msg.header.frame_id, "cam")
            self.assertEqual(msg.header.seq, k)
            self.assertAlmostEqual(msg.header.stamp.to_sec(), 100.0 + 0.2 * k, places=6)
            self.assertEqual(t, msg.header.stamp)
            self.assertEqual((msg.width, msg.height, msg.step, msg.encoding), (6, 4, 18, "rgb8"))
            pixels = np.frombuffer(msg.data, np.uint8).reshape(4, 6, 3)
            value = 10 * (k + 1)            # a.png, b.png, c.png
            np.testing.assert_array_equal(pixels[0, 0], (value + 1, 0, value))   # RGB order
            # shifted left by one: the distinct column moved from x=5 to x=4 and was replicated at x=5
            np.testing.assert_array_equal(pixels[0, 4], (202, 201, 200))
            np.testing.assert_array_equal(pixels[0, 5], (202, 201, 200))
            np.testing.assert_array_equal(pixels[0, 3], (value + 1, 0, value))

    def test_progress_goes_to_stderr_not_stdout(self):
        # Issue 33: printed only at the end. A line at every 10 % (3 images: 1/3 is 33 %, ...) with
        # --progress lines, none with off; stdout holds only the summary either way.
        bag_path = os.path.join(self.tmp, "out.bag")
        for mode, expected in (("lines", ["1/3 (33 %)", "2/3 (66 %)", "3/3 (100 %)"]), ("off", [])):
            with self.subTest(mode=mode), contextlib.redirect_stdout(io.StringIO()) as out, \
                    contextlib.redirect_stderr(io.StringIO()) as err:
                self.assertEqual(images_to_bag.main([self.folder, bag_path, "--progress", mode]), 0)
            self.assertEqual([line.split(": ")[1].split(",")[0] for line in err.getvalue().splitlines()], expected)
            self.assertEqual(len(out.getvalue().splitlines()), 1)
            self.assertTrue(out.getvalue().startswith("images_to_bag: wrote 3 images"))

    def test_mono_and_frame_selection(self):
        bag_path = os.path.join(self.tmp, "mono.bag")
        with contextlib.redirect_stdout(io.StringIO()):
            code = images_to_bag.main([self.folder, bag_path, "--encoding", "mono8", "--frames", "2,0"])
        self.assertEqual(code, 0)
        messages = self.read(bag_path)
        self.assertEqual([m.encoding for _, m, _ in messages], ["mono8", "mono8"])
        gray = [np.frombuffer(m.data, np.uint8).reshape(4, 6)[0, 0] for _, m, _ in messages]
        expected = [self.cv2.cvtColor(np.array([[[v, 0, v + 1]]], np.uint8), self.cv2.COLOR_BGR2GRAY)[0, 0]
                    for v in (30, 10)]
        self.assertEqual(gray, expected)
        self.assertEqual(messages[0][1].step, 6)

    def test_stamps_by_index_leave_gaps_where_frames_are_left_out(self):
        # Frames 0 and 2 of a.png, b.png, c.png at 2 Hz: by position 0.0 and 0.5 s after the start, by
        # index 0.0 and 1.0 s (frame 1, left out, leaves a gap as a dropout would).
        for option, expected in (([], [0.0, 0.5]), (["--stamp-by-index"], [0.0, 1.0])):
            bag_path = os.path.join(self.tmp, "stamps%d.bag" % len(option))
            with contextlib.redirect_stdout(io.StringIO()):
                code = images_to_bag.main([self.folder, bag_path, "--rate", "2", "--frames", "0,2",
                                           "--start-time", "100"] + option)
            self.assertEqual(code, 0)
            messages = self.read(bag_path)
            self.assertEqual([m.header.stamp.to_sec() - 100 for _, m, _ in messages], expected)
            self.assertEqual([t.to_sec() - 100 for _, _, t in messages], expected)
            self.assertEqual([m.header.seq for _, m, _ in messages], [0, 1])

    def test_unreadable_image_fails_without_leaving_a_bag(self):
        with open(os.path.join(self.folder, "d.png"), "w") as f:
            f.write("this is not a png")
        bag_path = os.path.join(self.tmp, "broken.bag")
        with contextlib.redirect_stderr(io.StringIO()) as err:
            code = images_to_bag.main([self.folder, bag_path])
        self.assertEqual(code, 2)
        self.assertIn("d.png", err.getvalue())
        self.assertFalse(os.path.exists(bag_path))
        self.assertFalse(os.path.exists(bag_path + ".tmp"))

    def test_missing_and_empty_folders(self):
        empty = os.path.join(self.tmp, "empty")
        os.makedirs(empty)
        with contextlib.redirect_stderr(io.StringIO()):
            self.assertEqual(images_to_bag.main([empty, os.path.join(self.tmp, "x.bag")]), 2)
            self.assertEqual(images_to_bag.main([os.path.join(self.tmp, "nope"), os.path.join(self.tmp, "x.bag")]), 2)

    def test_stamps_outside_ros_time_are_refused_by_name(self):
        # ROS time is unsigned 32-bit seconds: three frames at 1 Hz from 2^32 - 2 s end at 2^32 s.
        for start, rate in (("-5", "10"), ("1e12", "10"), (str(2 ** 32 - 2), "1")):
            bag_path = os.path.join(self.tmp, "stamps.bag")
            with contextlib.redirect_stderr(io.StringIO()) as err:
                code = images_to_bag.main([self.folder, bag_path, "--start-time", start, "--rate", rate])
            self.assertEqual(code, 2, start)
            self.assertIn("do not fit ROS time", err.getvalue())
            self.assertFalse(os.path.exists(bag_path))
        with contextlib.redirect_stderr(io.StringIO()) as err:
            self.assertEqual(images_to_bag.main([self.folder, bag_path, "--rate", "inf"]), 2)
        self.assertIn("rate must be > 0 and finite", err.getvalue())
        with contextlib.redirect_stdout(io.StringIO()):
            self.assertEqual(images_to_bag.main([self.folder, bag_path, "--start-time", str(2 ** 32 - 3),
                                                 "--rate", "1"]), 0)
        self.assertEqual([m.header.stamp.secs for _, m, _ in self.read(bag_path)],
                         [2 ** 32 - 3, 2 ** 32 - 2, 2 ** 32 - 1])

    def test_a_bag_inside_the_image_folder_is_refused_and_the_folder_kept(self):
        # Every image of the folder is the input: a bag named like a frame replaced it (exit 0).
        before = {n: open(os.path.join(self.folder, n), "rb").read() for n in os.listdir(self.folder)}
        for target in (os.path.join(self.folder, "b.png"), os.path.join(self.folder, "out.bag")):
            with contextlib.redirect_stderr(io.StringIO()) as err:
                self.assertEqual(images_to_bag.main([self.folder, target]), 2)
            self.assertIn("would be written inside the image folder", err.getvalue())
        self.assertEqual({n: open(os.path.join(self.folder, n), "rb").read() for n in os.listdir(self.folder)},
                         before)

    def test_a_topic_that_is_not_a_ros_name_is_refused_by_name(self):
        # rosbag refused '' with a ValueError traceback.
        bag_path = os.path.join(self.tmp, "topic.bag")
        for topic in ("", "two words", "/cam//image", "1cam", "/cam/"):
            with contextlib.redirect_stderr(io.StringIO()) as err:
                self.assertEqual(images_to_bag.main([self.folder, bag_path, "--topic", topic]), 2, topic)
            self.assertIn("topic '%s' is not a ROS topic name" % topic, err.getvalue())
            self.assertFalse(os.path.exists(bag_path))
        for topic in ("cam", "/cam/image_raw", "/a1/b_2"):
            with contextlib.redirect_stdout(io.StringIO()):
                self.assertEqual(images_to_bag.main([self.folder, bag_path, "--topic", topic]), 0, topic)
            self.assertEqual(set(t for t, _, _ in self.read(bag_path)), {topic})

    def test_a_shift_beyond_the_width_and_an_output_folder_are_refused_before_writing(self):
        # --shift-px 100000 wrote a bag of one edge column replicated; a folder as the output was written in
        # full, then refused by the rename.
        outputs = os.path.join(self.tmp, "out")
        os.makedirs(outputs)
        for argv, words in (([self.folder, os.path.join(outputs, "x.bag"), "--shift-px", "-6"],
                             "a shift of -6 px leaves nothing of the 6 px wide"),
                            ([self.folder, outputs], "the output %s is a folder; name the bag file to write" % outputs)):
            with contextlib.redirect_stderr(io.StringIO()) as err:
                self.assertEqual(images_to_bag.main(argv), 2, argv)
            self.assertIn(words, err.getvalue())
        self.assertEqual(os.listdir(outputs), [])
        with contextlib.redirect_stderr(io.StringIO()):  # 5 of the 6 columns replicated: still an image
            self.assertEqual(images_to_bag.main([self.folder, os.path.join(self.tmp, "y.bag"), "--shift-px", "5"]), 0)

    def test_images_of_different_sizes_are_refused(self):
        self.cv2.imwrite(os.path.join(self.folder, "z.png"), np.zeros((5, 6, 3), np.uint8))
        with contextlib.redirect_stderr(io.StringIO()):
            self.assertEqual(images_to_bag.main([self.folder, os.path.join(self.tmp, "x.bag")]), 2)


if __name__ == "__main__":
    unittest.main()
