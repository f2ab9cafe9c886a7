"""The closed-loop simulator's kinematics and route geometry (scripts/route_simulator) and the figures of
scripts/run_closed_loop, on hand-worked numbers."""

import math
import os
import sys
import tempfile
import argparse
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scripts_under_test  # noqa: E402

simulator = scripts_under_test.load("route_simulator")
closed_loop = scripts_under_test.load("run_closed_loop")
generate_route = scripts_under_test.load("generate_route")



class SummaryLineTest(unittest.TestCase):
    """The printed line for a run that never converged said "within 0.3 m after never m of route, median after -
    m" (a new-user trial on a 25 m route)."""

    def test_a_run_that_never_converged_says_so_and_one_that_did_says_where(self):
        run = {"mode": "homing", "completed": True, "result": "completed", "median_m": 0.05, "p95_m": 0.2,
               "max_m": 1.0, "converged_after_m": None, "median_after_convergence_m": float("nan")}
        self.assertTrue(closed_loop.summary_line(run).endswith(", never within 0.3 m for 10 m of route in a row"))
        run.update(converged_after_m=12.34, median_after_convergence_m=0.0314)
        self.assertTrue(closed_loop.summary_line(run).endswith(
            ", within 0.3 m (for 10 m in a row) after 12.3 m of route, median after 0.031 m"))

class StraightRoute:
    """A route along a heading, sampled like generate_route.Route (start, resolution, s, x, y, heading)."""

    def __init__(self, heading, length=20.0, resolution=0.05):
        self.start, self.resolution, self.length = -5.0, resolution, length
        self.s = np.arange(-5.0, length + 5.0 + resolution / 2, resolution)
        self.x = self.s * math.cos(heading)
        self.y = self.s * math.sin(heading)
        self.heading = np.full_like(self.s, heading)


class UnicycleTest(unittest.TestCase):
    def test_straight_with_scale_error(self):
        robot = simulator.Unicycle(0.0, 0.0, 0.0, scale_error=0.1)
        travelled = robot.step(1.0, 0.0, 1.0)
        self.assertAlmostEqual(robot.x, 1.1)
        self.assertAlmostEqual(robot.y, 0.0)
        self.assertAlmostEqual(travelled, 1.1)

    def test_quarter_circle(self):
        # v = 1 m/s, w = pi/2 rad/s for 1 s: a quarter of a circle of radius 2/pi, ending at (2/pi, 2/pi)
        robot = simulator.Unicycle(0.0, 0.0, 0.0)
        robot.step(1.0, math.pi / 2, 1.0)
        self.assertAlmostEqual(robot.x, 2 / math.pi)
        self.assertAlmostEqual(robot.y, 2 / math.pi)
        self.assertAlmostEqual(robot.yaw, math.pi / 2)

    def test_turn_rate_bias_turns_a_driven_robot_only(self):
        robot = simulator.Unicycle(1.0, 2.0, 0.0, turn_bias_rps=0.1)
        robot.step(0.0, 0.0, 2.0)  # told to stand: the base holds still
        self.assertEqual((robot.x, robot.y, robot.yaw), (1.0, 2.0, 0.0))
        robot.step(0.0, 0.05, 2.0)  # turning on the spot at 0.05 rad/s: 0.15 rad/s for 2 s
        self.assertAlmostEqual(robot.yaw, 0.3)
        self.assertEqual((robot.x, robot.y), (1.0, 2.0))
        # driving straight at 1 m/s for 1 s: an arc turning 0.1 rad, radius 10 m: x += 10 sin 0.1, y += 10 (1 - cos 0.1)
        robot = simulator.Unicycle(0.0, 0.0, 0.0, turn_bias_rps=0.1)
        robot.step(1.0, 0.0, 1.0)
        self.assertAlmostEqual(robot.yaw, 0.1)
        self.assertAlmostEqual(robot.x, 10.0 * math.sin(0.1))
        self.assertAlmostEqual(robot.y, 10.0 * (1.0 - math.cos(0.1)))

    def test_yaw_stays_wrapped(self):
        robot = simulator.Unicycle(0.0, 0.0, 3.0)
        robot.step(0.0, 1.0, 0.5)
        self.assertAlmostEqual(robot.yaw, 3.5 - 2 * math.pi)


class RouteProjectionTest(unittest.TestCase):
    def test_left_of_a_route_along_x_is_positive(self):
        projection = simulator.RouteProjection(StraightRoute(0.0))
        s, cross_track, heading = projection.project(5.0, 0.4)
        self.assertAlmostEqual(s, 5.0, places=6)
        self.assertAlmostEqual(cross_track, 0.4, places=6)
        self.assertAlmostEqual(heading, 0.0)

    def test_left_of_a_route_along_y_is_minus_x(self):
        projection = simulator.RouteProjection(StraightRoute(math.pi / 2))
        s, cross_track, _ = projection.project(0.5, 3.0)   # searched from 0 within 5 m
        self.assertAlmostEqual(s, 3.0, places=6)
        self.assertAlmostEqual(cross_track, -0.5, places=6)

    def test_taught_commands_drive_the_route(self):
        # The teach run's commands, integrated as a perfect unicycle, must end where the route ends: an
        # independent check of the curvature (finite differences of the route's heading).
        route = generate_route.Route(100.0, np.random.default_rng([3, 1]))
        x, y, yaw = route.pose(0.0)
        robot = simulator.Unicycle(x, y, yaw)
        s, dt = 0.0, 0.05
        while s < route.length:
            v, w = simulator.taught_command(route, s, 1.0)
            robot.step(v, w, dt)
            s += v * dt
        end_x, end_y, end_heading = route.pose(route.length)
        self.assertLess(math.hypot(robot.x - end_x, robot.y - end_y), 0.15)
        self.assertLess(abs(simulator.wrap_angle(robot.yaw - end_heading)), 0.01)


class FiguresTest(unittest.TestCase):
    def test_percentile_interpolates_like_numpy(self):
        self.assertAlmostEqual(closed_loop.percentile([4, 1, 3, 2], 50), 2.5)
        self.assertAlmostEqual(closed_loop.percentile([1, 2, 3, 4], 95), 3.85)
        self.assertAlmostEqual(closed_loop.percentile([1, 2, 3, 4], 95), float(np.percentile([1, 2, 3, 4], 95)))

    def test_samples_along_the_route_not_over_time(self):
        rows = [{"route_position_m": s, "cross_track_m": e}
                for s, e in ((0.0, 1.0), (0.05, 2.0), (0.1, 3.0), (0.1, 4.0), (0.1, 5.0), (0.25, 6.0))]
        self.assertEqual(closed_loop.along_route(rows), [(0.0, 1.0), (0.1, 3.0), (0.25, 6.0)])

    def test_convergence_distance(self):
        # within 0.3 m from 5 m on
        samples = [(float(s), 1.0 if s < 5 else 0.2) for s in range(31)]
        self.assertEqual(closed_loop.convergence_distance(samples), 5.0)
        # an excursion at 8 m: 5-7 m is less than 10 m within the bound, so from 9 m
        samples[8] = (8.0, -0.5)
        self.assertEqual(closed_loop.convergence_distance(samples), 9.0)
        # within the bound only for the last 3 m of the route: not converged (it may only be crossing it)
        self.assertIsNone(closed_loop.convergence_distance([(float(s), 1.0 if s < 27 else 0.1) for s in range(31)]))
        # within the bound for the last 10 m: converged
        self.assertEqual(closed_loop.convergence_distance([(float(s), 1.0 if s < 20 else 0.1) for s in range(31)]),
                         20.0)
        self.assertIsNone(closed_loop.convergence_distance([(float(s), 0.5) for s in range(31)]))
        # measured from the first sample
        self.assertEqual(closed_loop.convergence_distance([(2.0, 0.5), (3.0, 0.1), (20.0, 0.1)]), 1.0)

    def test_figures_of_a_trajectory_file(self):
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "run.csv")
            with open(path, "w") as f:
                f.write("time_s,x_m,y_m,yaw_rad,cmd_linear_mps,cmd_angular_rps,route_position_m,cross_track_m,"
                        "heading_error_rad\n")
                for k in range(301):   # 30 m: 1 m off for the first 2 m, then 0.1 m
                    f.write("%g,0,0,0,1,0,%g,%g,0\n" % (k * 0.1, k * 0.1, 1.0 if k < 20 else -0.1))
                f.write("# result: completed\n# odometry_scale_error: 0.01\n")
            rows, result = closed_loop.read_trajectory(path)
            self.assertEqual(result, "completed")
            times, linear, angular = simulator.read_commands(path)
            self.assertEqual(len(times), 301)
            self.assertEqual(linear[5], 1.0)
        f = closed_loop.figures(rows, result)
        self.assertTrue(f["completed"])
        self.assertAlmostEqual(f["converged_after_m"], 2.0)
        self.assertAlmostEqual(f["median_after_convergence_m"], 0.1)
        self.assertAlmostEqual(f["max_m"], 1.0)
        self.assertAlmostEqual(f["median_m"], 0.1)
        self.assertAlmostEqual(f["distance_m"], 30.0)

    def test_params_file_merges_the_given_sections(self):
        import yaml
        with tempfile.TemporaryDirectory() as folder:
            extra = os.path.join(folder, "extra.yaml")
            with open(extra, "w") as f:
                f.write("localizer:\n  max_shift_px: 6\nroute_follower:\n  homing_gain: 2.0\n")
            path = os.path.join(folder, "params.yaml")
            closed_loop.write_params(path, extra)
            with open(path) as f:
                params = yaml.safe_load(f)
            self.assertEqual(params, {"localizer": {"horizontal_fov_deg": 90.0, "max_shift_px": 6},
                                      "route_follower": {"homing_gain": 2.0}})
            closed_loop.write_params(path)
            with open(path) as f:
                self.assertEqual(yaml.safe_load(f), {"localizer": {"horizontal_fov_deg": 90.0, "max_shift_px": 8}})
            with open(extra, "w") as f:
                f.write("max_shift_px: 6\n")
            with self.assertRaises(ValueError):
                closed_loop.write_params(path, extra)

    def test_offsets(self):
        self.assertEqual(closed_loop.parse_offset("1:10"), (1.0, 10.0))
        self.assertEqual(closed_loop.parse_offset("-0.5:-5"), (-0.5, -5.0))
        self.assertEqual(closed_loop.offset_name((1.0, 10.0)), "+1m+10deg")
        self.assertEqual(closed_loop.parse_args(["--offsets=-1:-10,1:-10"]).offsets, [(-1.0, -10.0), (1.0, -10.0)])
        with self.assertRaises(Exception):
            closed_loop.parse_offset("1")
        # nan passed every check: roscore and teach.launch started, and the run failed 7 s later with "no
        # map was written", the reason only in a log.
        for bad in ("nan:nan", "nan:10", "1:inf", "5:10", "1:120"):
            with self.assertRaises(argparse.ArgumentTypeError, msg=bad):
                closed_loop.parse_offset(bad)

    def test_a_params_file_that_is_not_yaml_is_named(self):
        import tempfile
        with tempfile.TemporaryDirectory() as tmp:
            bad = os.path.join(tmp, "bad.yaml")
            with open(bad, "w") as f:
                f.write("localizer: [unclosed\n")
            with self.assertRaises(ValueError) as caught:  # a yaml traceback before
                closed_loop.write_params(os.path.join(tmp, "params.yaml"), bad)
            self.assertIn("bad.yaml is not YAML", str(caught.exception))

    def test_bad_arguments_are_refused_before_anything_starts(self):
        import contextlib
        import io
        import tempfile
        with tempfile.NamedTemporaryFile() as afile:
            for args, words in ((["--route-length-m", "nan"], "--route-length-m must be in [20, 1000], not nan"),
                                (["--route-length-m", "5000"], "--route-length-m must be in [20, 1000]"),
                                (["--seeds", "-3"], "--seeds must be >= 0"),
                                (["--output", afile.name], "is a file, not a folder"),
                                (["--follow-command", ""], "--follow-command '': no program given")):
                err = io.StringIO()
                with contextlib.redirect_stderr(err), self.assertRaises(SystemExit) as raised:
                    closed_loop.parse_args(args)
                self.assertEqual(raised.exception.code, 2, args)
                self.assertIn(words, err.getvalue())

    def test_a_follow_command_that_is_no_program_is_said_before_the_teach(self):
        import tempfile
        with tempfile.TemporaryDirectory() as tmp, self.assertRaises(SystemExit) as raised:
            closed_loop.main(["--output", tmp, "--seeds", "1", "--follow-command", "roslaunchh x follow.launch"])
        self.assertEqual(str(raised.exception.code),
                         "run_closed_loop: roslaunchh not found; source your workspace's devel/setup.bash")

    def test_an_output_folder_that_cannot_be_made_is_said_before_anything_starts(self):
        with self.assertRaises(SystemExit) as raised:  # a FileNotFoundError traceback before
            closed_loop.main(["--output", "/proc/along_route_x", "--seeds", "1"])
        self.assertEqual(str(raised.exception.code),
                         "run_closed_loop: --output /proc/along_route_x cannot be made: No such file or directory")

    def test_occlusion(self):
        self.assertEqual(closed_loop.parse_occlusion("40:10"), (40.0, 10.0))
        self.assertEqual(closed_loop.parse_args(["--occlusion", "0:2.5"]).occlusion, (0.0, 2.5))
        self.assertIsNone(closed_loop.parse_args([]).occlusion)
        for bad in ("40", "40:0", "-1:5", "a:b"):
            with self.assertRaises(argparse.ArgumentTypeError, msg=bad):
                closed_loop.parse_occlusion(bad)


class SimulatorOcclusionTest(unittest.TestCase):
    """The lens is covered in the repeat, from occlusion_start_s for occlusion_duration_s, and never in the teach."""

    def occluded(self, mode, elapsed, start=40.0, duration=10.0):
        sim = simulator.Simulator.__new__(simulator.Simulator)  # occluded() reads only the parameters
        sim.p = dict(simulator.PARAMS, mode=mode, occlusion_start_s=start, occlusion_duration_s=duration)
        return sim.occluded(elapsed)

    def test_window(self):
        self.assertFalse(self.occluded("repeat", 39.99))
        self.assertTrue(self.occluded("repeat", 40.0))
        self.assertTrue(self.occluded("repeat", 49.99))
        self.assertFalse(self.occluded("repeat", 50.0))
        self.assertFalse(self.occluded("teach", 45.0))
        self.assertFalse(self.occluded("repeat", 45.0, duration=0.0))


if __name__ == "__main__":
    unittest.main()


class SimulatorParamsTest(unittest.TestCase):
    """~route_length_m is bounded: the world is built in memory (12.5 GB measured for a 1900 m route)."""

    class FakeRospy:
        def __init__(self, given):
            self.given = given

        def get_param(self, name, default):
            return self.given.get(name.lstrip("~"), default)

    def problems(self, **given):
        return simulator.read_params(self.FakeRospy(given))[1]

    def test_route_length_bounds(self):
        self.assertEqual(self.problems(route_length_m=150.0), [])
        self.assertEqual(self.problems(route_length_m=1000.0), [])
        self.assertEqual(self.problems(route_length_m=1001.0),
                         ["~route_length_m must be <= 1000 (its world is built in memory), not 1001.0"])
        self.assertEqual(self.problems(route_length_m=5.0), ["~route_length_m must be >= 10"])
