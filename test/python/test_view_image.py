"""scripts/view_image (the viewer demo.launch view:=true starts): sensor_msgs/Image decoding, by hand-made
messages with padded rows."""

import contextlib
import ctypes.util
import io
import os
import sys
import types
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import load

view_image = load("view_image")


def message(encoding, width, height, step, data, is_bigendian=0):
    return types.SimpleNamespace(encoding=encoding, width=width, height=height, step=step, data=bytes(data),
                                 is_bigendian=is_bigendian)


class DecodeTest(unittest.TestCase):
    def test_bgr8_with_padded_rows(self):
        # 2 x 2 px, rows of 8 bytes (6 used + 2 padding).
        data = [1, 2, 3, 4, 5, 6, 99, 99,
                7, 8, 9, 10, 11, 12, 99, 99]
        image = view_image.decode(message('bgr8', 2, 2, 8, data))
        self.assertEqual(image.shape, (2, 2, 3))
        self.assertEqual(image[1, 0].tolist(), [7, 8, 9])
        self.assertEqual(image[0, 1].tolist(), [4, 5, 6])

    def test_rgb8_is_shown_as_bgr(self):
        image = view_image.decode(message('rgb8', 1, 1, 3, [10, 20, 30]))
        self.assertEqual(image[0, 0].tolist(), [30, 20, 10])

    def test_mono16_keeps_the_high_byte(self):
        little = np.array([[0x1234, 0xff00]], '<u2').tobytes()
        self.assertEqual(view_image.decode(message('mono16', 2, 1, 4, little)).tolist(), [[0x12, 0xff]])
        big = np.array([[0x1234, 0xff00]], '>u2').tobytes()
        self.assertEqual(view_image.decode(message('mono16', 2, 1, 4, big, is_bigendian=1)).tolist(), [[0x12, 0xff]])

    def test_other_encodings_are_refused_by_name(self):
        with self.assertRaisesRegex(ValueError, "32FC1"):
            view_image.decode(message('32FC1', 1, 1, 4, [0, 0, 0, 0]))

    def test_no_display_is_said_not_crashed(self):
        saved = {k: os.environ.pop(k) for k in ('DISPLAY', 'WAYLAND_DISPLAY') if k in os.environ}
        try:
            self.assertEqual(view_image.main([]), 1)
        finally:
            os.environ.update(saved)

    @unittest.skipUnless(ctypes.util.find_library('X11'), 'needs libX11 to ask the display')
    def test_a_display_that_cannot_be_opened_is_said_not_an_abort(self):
        saved = {k: os.environ.pop(k) for k in ('DISPLAY', 'WAYLAND_DISPLAY') if k in os.environ}
        os.environ['DISPLAY'] = ':97'  # no X server there (a stale ssh -X display)
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err):
                self.assertEqual(view_image.main([]), 1)
        finally:
            del os.environ['DISPLAY']
            os.environ.update(saved)
        self.assertIn('cannot open display :97', err.getvalue())


if __name__ == '__main__':
    unittest.main()
