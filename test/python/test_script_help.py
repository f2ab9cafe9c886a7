"""Every command-line script in scripts/ answers --help with its usage, exit status 0, and does nothing
else (issue 33: `run_demo --help` ran `mkdir --help`, `measure_nodelet_cpu --help` took --help for a
folder); an unknown option is refused, not taken for a folder."""

import os
import subprocess
import tempfile
import unittest

SCRIPTS_DIR = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'scripts'))
# (files only: loading a script as a module may leave a __pycache__ folder beside them)
SCRIPTS = sorted(name for name in os.listdir(SCRIPTS_DIR)
                 if not name.startswith('.') and os.path.isfile(os.path.join(SCRIPTS_DIR, name)))
BASH_SCRIPTS = [name for name in SCRIPTS if open(os.path.join(SCRIPTS_DIR, name)).readline().rstrip().endswith('bash')]
PYTHON_SCRIPTS = [name for name in SCRIPTS if name not in BASH_SCRIPTS]


def run(name, *args, cwd, extra_env=None):
    script = os.path.join(SCRIPTS_DIR, name)
    interpreter = ['bash'] if name in BASH_SCRIPTS else ['/usr/bin/python3']
    env = dict(os.environ, HOME=cwd, PATH='/usr/bin:' + os.environ.get('PATH', ''), **(extra_env or {}))
    return subprocess.run(interpreter + [script] + list(args), cwd=cwd, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, universal_newlines=True, timeout=60)


class ScriptHelpTest(unittest.TestCase):
    def test_every_script_is_covered(self):
        # The bash scripts found by their first line; a new script is checked without editing this test.
        for name in ('demo.sh', 'measure_nodelet_cpu', 'run_demo', 'run_sanitizers.sh', 'run_tests.sh', 'setup.sh'):
            self.assertIn(name, BASH_SCRIPTS)
        self.assertIn('generate_route', SCRIPTS)

    def test_help_prints_usage_and_creates_nothing(self):
        for name in SCRIPTS:
            for option in ('--help', '-h'):
                with self.subTest(script=name, option=option), tempfile.TemporaryDirectory() as folder:
                    done = run(name, option, cwd=folder)
                    self.assertEqual(done.returncode, 0, done.stderr)
                    self.assertIn('usage', done.stdout.lower())
                    self.assertNotIn('mkdir', done.stdout + done.stderr)  # run_demo ran `mkdir --help`
                    self.assertEqual(os.listdir(folder), [], 'created in the working folder / HOME')

    def test_the_python_scripts_run_from_the_checkout_without_a_sourced_workspace(self):
        # They import the package's Python module (src/along_route_localization): from the sourced workspace,
        # else from the checkout they are in. Here with no workspace: no ROS variables, no PYTHONPATH.
        self.assertIn('run_evaluation', PYTHON_SCRIPTS)
        for name in PYTHON_SCRIPTS:
            with self.subTest(script=name), tempfile.TemporaryDirectory() as folder:
                done = subprocess.run(['/usr/bin/python3', os.path.join(SCRIPTS_DIR, name), '--help'], cwd=folder,
                                      env={'PATH': '/usr/bin:/bin', 'HOME': folder, 'PYTHONDONTWRITEBYTECODE': '1'},
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, timeout=60)
                self.assertEqual(done.returncode, 0, done.stderr)
                self.assertIn('usage', done.stdout.lower())

    def test_output_into_a_closed_pipe_ends_quietly(self):
        # `evaluate ... | head -3` printed a BrokenPipeError traceback. The reader here closes before the script
        # writes: it ends with 141 (128 + SIGPIPE, as a Unix filter would), nothing on stderr (run_main).
        for name in PYTHON_SCRIPTS:
            with self.subTest(script=name), tempfile.TemporaryDirectory() as folder:
                env = dict(os.environ, HOME=folder, PATH='/usr/bin:' + os.environ.get('PATH', ''))
                process = subprocess.Popen(['/usr/bin/python3', os.path.join(SCRIPTS_DIR, name), '--help'], cwd=folder,
                                           env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                           universal_newlines=True)
                process.stdout.close()
                _, err = process.communicate(timeout=60)
                self.assertNotIn('BrokenPipeError', err)
                self.assertEqual(process.returncode, 141, err)

    def test_every_python_script_is_installed(self):
        # The scripts run and load each other from their own folder: run_evaluation runs cross_validate,
        # which was not installed.
        import re
        with open(os.path.join(SCRIPTS_DIR, '..', 'CMakeLists.txt')) as f:
            listed = re.search(r'catkin_install_python\(PROGRAMS(.*?)DESTINATION', f.read(), re.S).group(1).split()
        self.assertEqual(sorted(os.path.basename(path) for path in listed), PYTHON_SCRIPTS)

    def test_an_unknown_option_is_refused_not_taken_for_a_folder(self):
        for name in BASH_SCRIPTS:
            with self.subTest(script=name), tempfile.TemporaryDirectory() as folder:
                done = run(name, '--no-such-option', cwd=folder)
                self.assertEqual(done.returncode, 2, done.stdout + done.stderr)
                self.assertIn("unknown option '--no-such-option'", done.stderr)
                self.assertEqual(os.listdir(folder), [])


if __name__ == '__main__':
    unittest.main()


class MeasureNodeletCpuRateTest(unittest.TestCase):
    def test_a_rate_that_is_not_a_number_is_refused_not_run(self):
        # RATE_HZ went into Python source: 'abc' was a NameError traceback, and an expression was run.
        with tempfile.TemporaryDirectory() as tmp:
            marker = os.path.join(tmp, 'ran')
            for rate in ('abc', 'nan', '0', '-5', '__import__("os").mkdir("%s")' % marker):
                result = run('measure_nodelet_cpu', tmp, rate, cwd=tmp)
                self.assertEqual(result.returncode, 2, rate)
                self.assertIn("RATE_HZ must be a number in (0, 10000], not '%s'" % rate, result.stderr)
            self.assertFalse(os.path.exists(marker))

    def test_a_route_map_that_is_no_map_is_an_error_not_a_measurement(self):
        # A camera bag given as route_map.bag was measured without a word: no localizer line, exit 0.
        import shutil
        import signal
        import sys
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        from scripts_under_test import built_executable
        if not shutil.which('roslaunch', path='/usr/bin:' + os.environ.get('PATH', '')) or \
                not built_executable('localize_offline'):
            self.skipTest('needs ROS (roslaunch) and the sourced workspace')
        with tempfile.TemporaryDirectory() as tmp:
            write = ('import rosbag, rospy, sys\n'
                     'from sensor_msgs.msg import Image\n'
                     'with rosbag.Bag(sys.argv[1], "w") as bag:\n'
                     '    for k in range(3):\n'
                     '        m = Image(height=32, width=64, encoding="mono8", step=64, data=bytes(2048))\n'
                     '        m.header.stamp = rospy.Time(100 + 0.1 * k)\n'
                     '        bag.write("/camera/image_raw", m, m.header.stamp)\n')
            for name in ('repeat.bag', 'route_map.bag'):
                subprocess.run(['/usr/bin/python3', '-c', write, os.path.join(tmp, name)], check=True)
            # Its own session: on a timeout the whole group (roscore, roslaunch) is stopped, not bash alone.
            env = dict(os.environ, HOME=tmp, PATH='/usr/bin:' + os.environ.get('PATH', ''))
            process = subprocess.Popen(['bash', os.path.join(SCRIPTS_DIR, 'measure_nodelet_cpu'), tmp, '30'], cwd=tmp,
                                       env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                       universal_newlines=True, start_new_session=True)
            try:
                stdout, stderr = process.communicate(timeout=150)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGINT)
                stdout, stderr = process.communicate(timeout=30)
                self.fail('measure_nodelet_cpu did not finish in 150 s: %s' % stderr)
            result = subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)
            self.assertEqual(result.returncode, 1, result.stdout + result.stderr)
            self.assertIn('the localizer cannot localize with %s' % os.path.join(tmp, 'route_map.bag'), result.stderr)
            self.assertIn('not a map', result.stderr)  # the map reader's own reason
            self.assertNotIn('of one core', result.stdout)


class RunBenchmarksExitTest(unittest.TestCase):
    """A failing benchmark printed its table and exited 0; --repetitions -4 ran once; --from-json of a missing
    or foreign file was a traceback."""

    def fake_benchmark(self, tmp, exit_code):
        path = os.path.join(tmp, 'fakebench.sh')
        with open(path, 'w') as f:
            f.write('#!/bin/bash\nfor a in "$@"; do case "$a" in --benchmark_out=*) out="${a#*=}";; esac; done\n'
                    'echo \'{"context": {}, "benchmarks": []}\' > "$out"\nexit %d\n' % exit_code)
        os.chmod(path, 0o755)
        return path

    def test_a_failing_benchmark_exits_non_zero_after_its_table(self):
        with tempfile.TemporaryDirectory() as tmp:
            common = ['--filter', 'BM_None', '--repetitions', '1']
            no_data = {'ALONG_ROUTE_NORDLAND': os.path.join(tmp, 'none')}  # the default's frames missing: left out
            failing = run('run_benchmarks', '--benchmark', self.fake_benchmark(tmp, 3), *common, cwd=tmp,
                          extra_env=no_data)
            self.assertEqual(failing.returncode, 1, failing.stderr)
            self.assertIn('Times per iteration', failing.stdout)
            self.assertIn('run_benchmarks: the benchmark exited with 3', failing.stderr)
            passing = run('run_benchmarks', '--benchmark', self.fake_benchmark(tmp, 0), *common, cwd=tmp,
                          extra_env=no_data)
            self.assertEqual(passing.returncode, 0, passing.stderr)
            # Named by hand, a folder without the frames is a mistake: it printed an ERROR row and exited 0.
            named = run('run_benchmarks', '--benchmark', self.fake_benchmark(tmp, 0), *common, '--nordland',
                        os.path.join(tmp, 'none'), cwd=tmp)
            self.assertEqual(named.returncode, 2, named.stderr)
            self.assertIn('--nordland %s holds no summer/ and winter/ folders' % os.path.join(tmp, 'none'),
                          named.stderr)

    def test_bad_options_are_refused_by_name(self):
        with tempfile.TemporaryDirectory() as tmp:
            result = run('run_benchmarks', '--repetitions', '-4', cwd=tmp)
            self.assertEqual(result.returncode, 2)
            self.assertIn('--repetitions must be at least 1, got -4', result.stderr)
            result = run('run_benchmarks', '--json-out', os.path.join(tmp, 'nodir', 'b.json'), cwd=tmp)
            self.assertEqual(result.returncode, 2)
            self.assertIn('its folder does not exist', result.stderr)
            listed = os.path.join(tmp, 'list.json')
            with open(listed, 'w') as f:
                f.write('[]')
            for path, words in ((os.path.join(tmp, 'missing.json'), 'No such file'),
                                (listed, 'is not a Google Benchmark JSON output')):
                result = run('run_benchmarks', '--from-json', path, cwd=tmp)
                self.assertEqual(result.returncode, 2, result.stderr)
                self.assertIn(words, result.stderr)
                self.assertNotIn('Traceback', result.stderr)
