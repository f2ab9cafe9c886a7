"""along_route_localization.script_support (src/along_route_localization): what the scripts share, each function
on cases worked out by hand."""

import os
import stat
import subprocess
import sys
import tempfile
import unittest

REPOSITORY = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.append(os.path.join(REPOSITORY, "src"))  # without a sourced workspace: the checkout's package
from along_route_localization import script_support  # noqa: E402


class TestResultsTest(unittest.TestCase):
    def test_each_test_counts_once_and_a_rostest_whose_node_failed_counts_as_failed(self):
        # What catkin run_tests wrote when teach_full_disk's setUpClass failed: the wrapper passed (1 case, ok),
        # the test node's own file had 0 tests and 1 error; the summary said "0 failed".
        files = {
            "gtest-test_core.xml": '<testsuites tests="5" failures="1" errors="0" disabled="1">'
                                   '<testsuite name="A" tests="3" failures="1" errors="0" disabled="1"/>'
                                   '<testsuite name="B" tests="2" failures="0" errors="0"/></testsuites>',
            "rostest-test_rostest_teach_full_disk.xml": '<testsuite tests="1" failures="0" errors="0"/>',
            "rosunit-teach_full_disk.xml": '<testsuite tests="0" failures="0" errors="1"/>',
            "rostest-test_rostest_teach.xml": '<testsuite tests="1" failures="0" errors="0"/>',
            "rosunit-teach.xml": '<testsuite tests="6" failures="0" errors="0" skipped="2"/>',
            "rostest-test_rostest_crashed.xml": '<testsuite tests="1" failures="1" errors="0"/>',
            "MISSING-rosunit-crashed.xml": "",
            "broken.xml": "<testsuite tests=",
        }
        with tempfile.TemporaryDirectory() as tmp:
            os.makedirs(os.path.join(tmp, "along_route_localization"))
            for name, text in files.items():
                with open(os.path.join(tmp, "along_route_localization", name), "w") as f:
                    f.write(text)
            # tests: 3 + 2 (gtest suites) + 1 (the node's error) + 6 + 1 (the crashed wrapper) + 1 + 1
            # failed: 1 + 1 + 1 + 1 (MISSING) + 1 (does not parse); skipped: 1 (disabled) + 2
            self.assertEqual(script_support.count_test_results(tmp), (15, 5, 3))

    def test_a_skip_counts_whether_the_suite_or_only_its_test_case_says_so(self):
        # GoogleTest 1.10 (Ubuntu 20.04) writes a skip only on the test case, result="skipped", and counts it
        # in tests=; its skips were counted as passed. 1.12 (Debian 12) says it on both: counted once.
        files = {
            "gtest-focal.xml": '<testsuites><testsuite name="A" tests="3" failures="0" errors="0" disabled="1">'
                               '<testcase name="a" status="run" result="completed"/>'
                               '<testcase name="b" status="run" result="skipped"/>'
                               '<testcase name="DISABLED_c" status="notrun" result="suppressed"/>'
                               '</testsuite></testsuites>',
            "gtest-bookworm.xml": '<testsuites><testsuite name="B" tests="2" failures="0" errors="0" skipped="1">'
                                  '<testcase name="d" status="run" result="completed"/>'
                                  '<testcase name="e" status="run" result="skipped"><skipped message=""/></testcase>'
                                  '</testsuite></testsuites>',
            "rosunit-python.xml": '<testsuite tests="2" failures="0" errors="0">'
                                  '<testcase name="f"/><testcase name="g"><skipped type="skip"/></testcase>'
                                  '</testsuite>',
        }
        with tempfile.TemporaryDirectory() as tmp:
            for name, text in files.items():
                with open(os.path.join(tmp, name), "w") as f:
                    f.write(text)
            # tests 3 + 2 + 2; skipped: b and DISABLED_c, e, g
            self.assertEqual(script_support.count_test_results(tmp), (7, 0, 4))


class RunMainTest(unittest.TestCase):
    """run_main: into a closed pipe a script ends with 141 and no traceback, its own `finally` blocks run
    (setting SIGPIPE's default action instead left run_closed_loop's roscore and launches running)."""

    def run_script(self, body, folder):
        script = os.path.join(folder, 'script.py')
        with open(script, 'w') as f:
            f.write('import sys\nsys.path.insert(0, %r)\nfrom along_route_localization.script_support import run_main\n'
                    '%s\nrun_main(main)\n' % (os.path.join(os.path.dirname(script_support.__file__), '..'), body))
        process = subprocess.Popen([sys.executable, script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   universal_newlines=True)
        process.stdout.close()  # the reader is gone before the script writes
        _, err = process.communicate(timeout=30)
        return process.returncode, err

    def run_cleaning_script(self, statements):
        """run_script of a main() that runs `statements` in a try whose finally block leaves a file; (status,
        stderr, whether the file is there)."""
        with tempfile.TemporaryDirectory() as folder:
            marker = os.path.join(folder, 'cleaned')
            body = ('def main():\n    try:\n%s    finally:\n        open(%r, "w").close()\n'
                    % (''.join('        %s\n' % line for line in statements), marker))
            status, err = self.run_script(body, folder)
            return status, err, os.path.exists(marker)

    def test_a_closed_pipe_ends_the_script_after_its_finally_blocks(self):
        status, err, cleaned = self.run_cleaning_script(['for i in range(100000):', '    print("line", i)',
                                                         'return 0'])
        self.assertEqual(status, 141, err)
        self.assertEqual(err, '')
        self.assertTrue(cleaned, 'the finally block did not run')

    def test_ctrl_c_ends_the_script_after_its_finally_blocks_without_a_traceback(self):
        status, err, cleaned = self.run_cleaning_script(['raise KeyboardInterrupt'])
        self.assertEqual(status, 130, err)
        self.assertEqual(err, '\nscript.py: interrupted; what it wrote so far may be incomplete\n')
        self.assertTrue(cleaned, 'the finally block did not run')

    def test_a_status_and_a_systemexit_pass_through(self):
        with tempfile.TemporaryDirectory() as folder:
            self.assertEqual(self.run_script('def main():\n    return 3\n', folder), (3, ''))
            status, err = self.run_script('def main():\n    sys.exit("refused")\n', folder)
            self.assertEqual((status, err.strip()), (1, 'refused'))
            status, err = self.run_script('def main():\n    raise ValueError("a bug")\n', folder)
            self.assertEqual(status, 1)
            self.assertIn('ValueError: a bug', err)  # other errors keep their traceback


class SeasonTest(unittest.TestCase):
    def test_each_season_gives_the_other(self):
        self.assertEqual(script_support.other_season("summer"), "winter")
        self.assertEqual(script_support.other_season("winter"), "summer")

    def test_anything_else_is_refused_not_taken_for_winter(self):
        # run_evaluation's copy gave 'summer' for every word but 'summer'
        for word in ("autumn", "Summer", "", "winter "):
            with self.assertRaises(ValueError, msg=repr(word)):
                script_support.other_season(word)

    def test_the_nordland_frames_lie_beside_the_scripts_repository(self):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = os.path.realpath(tmp)
            script = os.path.join(tmp, "repo", "scripts", "run_evaluation")
            os.makedirs(os.path.dirname(script))
            open(script, "w").close()
            link = os.path.join(tmp, "elsewhere")
            os.makedirs(link)
            os.symlink(script, os.path.join(link, "run_evaluation"))
            expected = os.path.join(tmp, "shared", "data", "nordland")
            self.assertEqual(script_support.nordland_data_dir(script), expected)
            # through a link to the script: beside the repository that holds it, not beside the link
            self.assertEqual(script_support.nordland_data_dir(os.path.join(link, "run_evaluation")), expected)


class InsideFolderTest(unittest.TestCase):
    def setUp(self):
        self.folder = tempfile.TemporaryDirectory()
        self.tmp = os.path.realpath(self.folder.name)
        self.data = os.path.join(self.tmp, "data")
        os.makedirs(os.path.join(self.data, "summer"))

    def tearDown(self):
        self.folder.cleanup()

    def test_the_folder_itself_and_anything_under_it(self):
        inside = script_support.inside_folder
        self.assertTrue(inside(self.data, self.data))
        self.assertTrue(inside(self.data + os.sep, self.data))
        self.assertTrue(inside(self.data, self.data + os.sep))
        self.assertTrue(inside(os.path.join(self.data, "summer"), self.data))
        self.assertTrue(inside(os.path.join(self.data, "not", "made", "yet"), self.data))

    def test_a_sibling_whose_name_starts_the_same_is_outside(self):
        self.assertFalse(script_support.inside_folder(os.path.join(self.tmp, "data2"), self.data))
        self.assertFalse(script_support.inside_folder(os.path.join(self.tmp, "dat"), self.data))
        self.assertFalse(script_support.inside_folder(self.tmp, self.data))  # the parent

    def test_dot_dot_is_resolved(self):
        self.assertFalse(script_support.inside_folder(os.path.join(self.data, "summer", "..", "..", "out"), self.data))
        self.assertTrue(script_support.inside_folder(os.path.join(self.tmp, "x", "..", "data", "out"), self.data))

    def test_relative_paths_are_taken_from_the_working_folder(self):
        before = os.getcwd()
        os.chdir(self.data)
        try:
            self.assertTrue(script_support.inside_folder("out", self.data))
            self.assertTrue(script_support.inside_folder(".", self.data))
            self.assertTrue(script_support.inside_folder(os.path.join(self.tmp, "data", "out"), "."))
            self.assertFalse(script_support.inside_folder(os.path.join("..", "out"), self.data))
            self.assertFalse(script_support.inside_folder(os.path.join("..", "out"), "."))
        finally:
            os.chdir(before)

    def test_symbolic_links_are_followed_either_way(self):
        into = os.path.join(self.tmp, "link_into_data")
        os.symlink(self.data, into)
        # a path through a link that leads inside is inside
        self.assertTrue(script_support.inside_folder(os.path.join(into, "out"), self.data))
        # the folder given through a link: the same folder
        self.assertTrue(script_support.inside_folder(os.path.join(self.data, "out"), into))
        # a link inside the folder that leads out of it: where it leads counts
        out = os.path.join(self.tmp, "out")
        os.makedirs(out)
        os.symlink(out, os.path.join(self.data, "link_out"))
        self.assertFalse(script_support.inside_folder(os.path.join(self.data, "link_out", "x"), self.data))

    def test_everything_is_inside_the_root(self):
        self.assertTrue(script_support.inside_folder(self.data, os.sep))


class TopicNameTest(unittest.TestCase):
    def test_names_a_bag_can_hold(self):
        for topic in ("/camera/image_raw", "camera", "/a1/b_2", "a"):
            self.assertIsNone(script_support.topic_name_problem(topic), topic)

    def test_other_names_are_said_why(self):
        for topic in ("1camera", "/camera//image", "/camera/", "camera image", "", "/", "cam-era", "/~a"):
            problem = script_support.topic_name_problem(topic)
            self.assertIsNotNone(problem, topic)
            self.assertIn("topic '%s' is not a ROS topic name" % topic, problem)


class LoadScriptTest(unittest.TestCase):
    def test_the_script_beside_the_caller_is_loaded_through_links(self):
        with tempfile.TemporaryDirectory() as tmp:
            scripts = os.path.join(tmp, "scripts")
            os.makedirs(scripts)
            with open(os.path.join(scripts, "helper"), "w") as f:
                f.write("#!/usr/bin/env python3\nVALUE = 41 + 1\n")
            caller = os.path.join(scripts, "caller")
            open(caller, "w").close()
            elsewhere = os.path.join(tmp, "bin")
            os.makedirs(elsewhere)
            os.symlink(caller, os.path.join(elsewhere, "caller"))  # no helper beside the link
            for beside in (caller, os.path.join(elsewhere, "caller")):
                module = script_support.load_script("helper", beside)
                self.assertEqual(module.VALUE, 42)
                self.assertEqual(module.__name__, "helper")
            with self.assertRaises(FileNotFoundError):
                script_support.load_script("missing", caller)

    def test_each_load_is_a_module_of_its_own(self):
        # loaded, not imported: nothing is left in sys.modules, and a second load starts afresh
        with tempfile.TemporaryDirectory() as tmp:
            with open(os.path.join(tmp, "counter_script"), "w") as f:
                f.write("COUNT = [0]\n")
            first = script_support.load_script("counter_script", os.path.join(tmp, "caller"))
            first.COUNT[0] += 1
            second = script_support.load_script("counter_script", os.path.join(tmp, "caller"))
            self.assertEqual(second.COUNT, [0])
            self.assertNotIn("counter_script", sys.modules)


class CandidatesTest(unittest.TestCase):
    def test_no_lines_are_the_defaults_alone(self):
        self.assertEqual(script_support.parse_candidates(""), [("defaults", [])])
        self.assertEqual(script_support.parse_candidates("# only a comment\n\n   \n"), [("defaults", [])])

    def test_comments_after_a_candidate_and_spaces_are_dropped(self):
        self.assertEqual(script_support.parse_candidates("  steep :  max_step=3   # steeper\nnone:\n"),
                         [("defaults", []), ("steep", ["max_step=3"]), ("none", [])])

    def test_a_defaults_line_without_settings_is_the_defaults_once(self):
        self.assertEqual(script_support.parse_candidates("defaults:\nsteep: max_step=3\ndefaults:  # again\n"),
                         [("defaults", []), ("steep", ["max_step=3"])])

    def test_defaults_with_settings_is_a_name_used_twice(self):
        with self.assertRaises(ValueError) as caught:
            script_support.parse_candidates("defaults: max_step=3\n")
        self.assertEqual(str(caught.exception), "candidates line 1: the name 'defaults' is used twice")

    def test_malformed_lines_are_named_by_their_number_in_the_file(self):
        for text, message in (("# a\n\nsteep max_step=3\n", "candidates line 3: expected 'name: name=value ...', "
                                                              "got 'steep max_step=3'"),
                              (": max_step=3\n", "candidates line 1: expected 'name: name=value ...', got ': max_step=3'"),
                              ("two words: max_step=3\n", "candidates line 1: expected 'name: name=value ...', "
                                                          "got 'two words: max_step=3'"),
                              ("a: max_step=3 =4\n", "candidates line 1: '=4' is not name=value"),
                              ("a: max_step\n", "candidates line 1: 'max_step' is not name=value"),
                              ("a: x=1\n\na: y=2\n", "candidates line 3: the name 'a' is used twice")):
            with self.assertRaises(ValueError, msg=text) as caught:
                script_support.parse_candidates(text)
            self.assertEqual(str(caught.exception), message)

    def test_a_value_may_hold_colons_and_equals_signs(self):
        # only the first ':' ends the name, only the first '=' the parameter's name
        self.assertEqual(script_support.parse_candidates("a: path=x:y b=c=d\n"), [("defaults", []),
                                                                                ("a", ["path=x:y", "b=c=d"])])

    def test_every_candidate_runs_with_the_calibration_off_last(self):
        self.assertEqual(script_support.set_arguments(["max_step=3", "filter_window=5"]),
                         ["--set", "max_step=3", "--set", "filter_window=5", "--set", "calibration_slope=0"])
        self.assertEqual(script_support.set_arguments([]), ["--set", "calibration_slope=0"])


class FakeLocalizerTest(unittest.TestCase):
    """run and check_candidates with a stand-in for localize_offline --check-params that refuses max_stpe."""

    def setUp(self):
        self.folder = tempfile.TemporaryDirectory()
        self.calls = os.path.join(self.folder.name, "calls")
        self.binary = os.path.join(self.folder.name, "localize_offline")
        with open(self.binary, "w") as f:
            f.write('#!/bin/sh\necho "$*" >> "%s"\necho "checked $*"\n'
                    'case "$*" in *max_stpe=*) echo "unknown parameter \'max_stpe\'" >&2; exit 2;; esac\n'
                    'exit 0\n' % self.calls)
        os.chmod(self.binary, os.stat(self.binary).st_mode | stat.S_IXUSR)

    def tearDown(self):
        self.folder.cleanup()

    def calls_made(self):
        with open(self.calls) as f:
            return f.read().splitlines()

    def test_run_gives_the_output_and_logs_the_command(self):
        log = os.path.join(self.folder.name, "run.log")
        seconds, out, err = script_support.run([self.binary, "--check-params"], log)
        self.assertGreaterEqual(seconds, 0.0)
        self.assertEqual((out, err), ("checked --check-params\n", ""))
        with open(log) as f:
            self.assertEqual(f.read(), "$ %s --check-params\nchecked --check-params\n" % self.binary)

    def test_a_failed_command_is_an_evaluation_error_with_its_exit_and_words(self):
        with self.assertRaises(script_support.EvaluationError) as caught:
            script_support.run([self.binary, "--set", "max_stpe=3"])
        self.assertEqual(str(caught.exception), "command failed (exit 2): %s --set max_stpe=3\n"
                                                "unknown parameter 'max_stpe'" % self.binary)

    def test_every_candidate_is_checked_with_the_calibration_off(self):
        script_support.check_candidates(self.binary, [("defaults", []), ("steep", ["max_step=3"])])
        self.assertEqual(self.calls_made(), ["--check-params --method dtw --set calibration_slope=0",
                                             "--check-params --method dtw --set max_step=3 --set calibration_slope=0"])

    def test_the_first_refused_candidate_is_named_and_the_rest_not_run(self):
        candidates = script_support.parse_candidates("steep: max_step=3\ntypo: max_stpe=3\nlater: max_step=2\n")
        with self.assertRaises(script_support.EvaluationError) as caught:
            script_support.check_candidates(self.binary, candidates)
        self.assertTrue(str(caught.exception).startswith("candidate typo: command failed (exit 2): "),
                        str(caught.exception))
        self.assertIn("unknown parameter 'max_stpe'", str(caught.exception))
        self.assertEqual(len(self.calls_made()), 3)  # defaults, steep, typo; not later

    def test_an_explicit_localize_offline_must_be_an_executable_file(self):
        self.assertEqual(script_support.find_localize_offline(self.binary), self.binary)
        for path in (self.calls, os.path.join(self.folder.name, "none"), self.folder.name):
            if path == self.calls:
                open(path, "w").close()
            with self.assertRaises(script_support.EvaluationError) as caught:
                script_support.find_localize_offline(path)
            self.assertEqual(str(caught.exception), "--localize-offline %s is not an executable file" % path)


class DataAndOutputTest(unittest.TestCase):
    def test_the_data_needs_both_seasons(self):
        with tempfile.TemporaryDirectory() as tmp:
            os.makedirs(os.path.join(tmp, "summer"))
            with self.assertRaises(script_support.EvaluationError) as caught:
                script_support.check_data(tmp)
            self.assertIn("(missing: winter)", str(caught.exception))
            os.makedirs(os.path.join(tmp, "winter"))
            script_support.check_data(tmp)

    def test_an_output_inside_the_data_is_refused_and_one_beside_it_taken(self):
        with tempfile.TemporaryDirectory() as tmp:
            data = os.path.join(tmp, "nordland")
            os.makedirs(data)
            with self.assertRaises(script_support.EvaluationError) as caught:
                script_support.check_output(os.path.join(data, "out"), data)
            self.assertEqual(str(caught.exception), "--output %s is inside the data folder %s; write it elsewhere"
                             % (os.path.join(data, "out"), data))
            script_support.check_output(os.path.join(tmp, "nordland_out"), data)


if __name__ == "__main__":
    unittest.main()
