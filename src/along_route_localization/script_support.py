"""What the package's command-line scripts (scripts/, no .py suffix) share.

- the Nordland seasons (other_season) and where the frames are by default (nordland_data_dir)
- whether a path lies inside a folder (inside_folder) and whether a ROS topic name is one a bag can hold
- one script loaded from another as a module (load_script)
- how every script ends (run_main): quietly when its output goes into a pipe that closed early (`| head`)
- the steps run_evaluation and cross_validate share: running a command (run, EvaluationError), finding
  localize_offline, checking the data and the output folder, seed lists, and cross_validate's candidate
  settings (parse_candidates, check_candidates), which run_evaluation checks before anything is written

The scripts import it from the sourced catkin workspace (devel or install space); run from a source checkout
without one, they find it in the repository's src/.
"""

import importlib.machinery
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import time

SEASONS = ("summer", "winter")


def run_main(main, *args):
    """Runs a script's main(*args) and exits with what it returns. Output into a pipe whose reader has gone
    (`evaluate ... | head -3`) ends it with status 141 (128 + SIGPIPE, as a Unix filter ends) and nothing on
    stderr, instead of a BrokenPipeError traceback. Not by SIGPIPE itself: the script's own `finally` blocks
    still run (run_closed_loop stops the roscore and launches it started, others remove temporary folders).
    Ctrl-C (SIGINT) ends it the same way, after those blocks, with 130 and one line instead of a traceback."""
    try:
        try:
            status = main(*args)
        finally:
            sys.stdout.flush()  # inside the try: a closed pipe fails here, not at the interpreter's exit
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # what is still buffered goes nowhere
        status = 141
    except KeyboardInterrupt:
        sys.stderr.write("\n%s: interrupted; what it wrote so far may be incomplete\n"
                         % os.path.basename(sys.argv[0]))
        status = 130
    sys.exit(status)


def other_season(season):
    """The other Nordland season: 'summer' -> 'winter', 'winter' -> 'summer'. ValueError for anything else."""
    if season not in SEASONS:
        raise ValueError("'%s' is not a season (%s)" % (season, ", ".join(SEASONS)))
    return SEASONS[1 - SEASONS.index(season)]


def nordland_data_dir(script):
    """The Nordland frames' default folder for the script whose file is `script` (its __file__): the
    shared/data/nordland beside the repository that holds the script (symlinks resolved)."""
    return os.path.normpath(os.path.join(os.path.dirname(os.path.realpath(script)), "..", "..", "shared", "data",
                                         "nordland"))


def keep_earlier_outputs(folder, names):
    """Renames each of `names` in `folder` that an earlier run left (results.md -> results.previous.md), so that
    a run that stops half way leaves no tables beside runs they do not describe; returns (name, new name) of each
    one renamed."""
    moved = []
    for name in names:
        stem, extension = os.path.splitext(name)
        if os.path.exists(os.path.join(folder, name)):
            os.replace(os.path.join(folder, name), os.path.join(folder, stem + ".previous" + extension))
            moved.append((name, stem + ".previous" + extension))
    return moved


def inside_folder(path, folder):
    """Whether `path` is `folder` itself or lies anywhere under it, with symlinks resolved and relative paths
    taken from the working folder. Neither has to exist (a folder about to be made is checked too)."""
    inner, outer = os.path.realpath(path), os.path.realpath(folder)
    return inner == outer or inner.startswith(outer.rstrip(os.sep) + os.sep)


def same_file(a, b):
    """Whether two paths name one file: equal with symlinks resolved, or, when both exist, one inode (a hard
    link). Neither has to exist."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def output_input_clash(outputs, inputs):
    """The first output that names an input file, or another output: "--write-results 'x.csv' names the same
    file as --ground-truth"; None when none does. outputs and inputs: (option, path) pairs, path None when
    not given. A tool that opened its output first would destroy the input it was about to read."""
    given_inputs = [(option, path) for option, path in inputs if path]
    given_outputs = [(option, path) for option, path in outputs if path]
    for i, (option, path) in enumerate(given_outputs):
        for other, other_path in given_inputs + given_outputs[:i]:
            if same_file(path, other_path):
                return "%s '%s' names the same file as %s; choose another file" % (option, path, other)
    return None


def count_test_results(folder):
    """(tests, failed, skipped) of the JUnit XML files catkin's run_tests wrote under `folder`, each test once:
    a gtest's own file (gtest-*.xml), a rostest's test node's (rosunit-*.xml), the launch checks'. A rostest's
    wrapper (rostest-*.xml) holds one case that passes whenever its launch ran, so only a failure there counts
    (the test node never reported); a file catkin names MISSING-* or one that does not parse is a failure."""
    import glob
    import xml.etree.ElementTree as ET
    tests = failed = skipped = 0
    for path in sorted(glob.glob(os.path.join(folder, "**", "*.xml"), recursive=True)):
        name = os.path.basename(path)
        if name.startswith("MISSING-"):
            tests, failed = tests + 1, failed + 1
            continue
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError:
            tests, failed = tests + 1, failed + 1
            continue
        for suite in [root] if root.tag == "testsuite" else root.findall("testsuite"):
            bad = int(suite.get("failures", 0)) + int(suite.get("errors", 0))
            if name.startswith("rostest-"):
                tests, failed = tests + bad, failed + bad
                continue
            tests += max(int(suite.get("tests", 0)), bad)
            failed += bad
            skipped += suite_skipped(suite)
    return tests, failed, skipped


def suite_skipped(suite):
    """The skipped and disabled tests of a JUnit <testsuite>: from its <testcase>s when it lists them (GoogleTest
    1.10, Ubuntu 20.04's, marks a skip only there, result="skipped", without the suite's skipped= that 1.11 added;
    a disabled one is status="notrun"), else from the suite's skipped= or disabled= count."""
    cases = suite.findall("testcase")
    if cases:
        return sum(1 for case in cases
                   if case.get("result") in ("skipped", "suppressed") or case.get("status") == "notrun" or
                   case.find("skipped") is not None)
    return int(suite.get("skipped", 0) or suite.get("disabled", 0) or 0)


TOPIC_NAME = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


def topic_name_problem(topic):
    """None when `topic` is a ROS graph name a bag can hold (letters, digits, _ and /, each part starting
    with a letter); else the sentence that says why not (rosbag's own is a ValueError traceback)."""
    if TOPIC_NAME.match(topic):
        return None
    return "topic '%s' is not a ROS topic name (parts of letters, digits and _, each starting with a " \
           "letter, joined by /)" % topic


def load_script(name, beside):
    """The script `name` (no .py suffix) in the folder of the file `beside` (the calling script's __file__,
    symlinks resolved), imported as a module of that name. FileNotFoundError when it is not there."""
    path = os.path.join(os.path.dirname(os.path.realpath(beside)), name)
    loader = importlib.machinery.SourceFileLoader(name, path)
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(name, loader))
    loader.exec_module(module)
    return module


# ---------------------------------------------------------------------------------------------
# The evaluation's steps (run_evaluation, cross_validate)
# ---------------------------------------------------------------------------------------------

class EvaluationError(Exception):
    """A step of an evaluation failed: the scripts report it as one line and a non-zero exit."""


def run(command, log_path=None):
    """Runs a command; returns (seconds, stdout, stderr), and writes the command and its output to log_path
    when given. Raises EvaluationError on failure."""
    start = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True)
    seconds = time.monotonic() - start
    if log_path:
        with open(log_path, "w") as f:
            f.write("$ %s\n%s%s" % (" ".join(command), result.stdout, result.stderr))
    if result.returncode != 0:
        raise EvaluationError("command failed (exit %d): %s\n%s" % (result.returncode, " ".join(command),
                                                                      (result.stderr or result.stdout).strip()))
    return seconds, result.stdout, result.stderr


def find_localize_offline(explicit):
    """Path of the localize_offline executable: --localize-offline, else the sourced catkin workspace."""
    if explicit:
        if not (os.path.isfile(explicit) and os.access(explicit, os.X_OK)):
            raise EvaluationError("--localize-offline %s is not an executable file" % explicit)
        return explicit
    candidates = []
    if shutil.which("catkin_find"):
        try:
            out = subprocess.run(["catkin_find", "--without-underlays", "--libexec", "along_route_localization",
                                  "localize_offline"], capture_output=True, text=True, timeout=60).stdout
            candidates += out.split()
        except (OSError, subprocess.SubprocessError):
            pass
    for prefix in os.environ.get("CMAKE_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            candidates.append(os.path.join(prefix, "lib", "along_route_localization", "localize_offline"))
    for path in candidates:
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path
    raise EvaluationError("localize_offline not found: build the package (catkin_make) and source its "
                          "devel/setup.bash, or pass --localize-offline PATH")


def check_data(data):
    """Refuses a Nordland folder without summer/ and winter/."""
    missing = [s for s in SEASONS if not os.path.isdir(os.path.join(data, s))]
    if missing:
        raise EvaluationError("Nordland data not found: %s needs the folders summer/ and winter/ (missing: %s). "
                              "Pass its location with --data." % (data, ", ".join(missing)))


def check_output(output, data):
    """Refuses an output folder inside the data folder: make_nordland_scenarios refuses it too, but only
    after an evaluation had made its folders there."""
    if inside_folder(output, data):
        raise EvaluationError("--output %s is inside the data folder %s; write it elsewhere" % (output, data))


MAX_SEEDS = 1000  # each seed is a localize_offline run per scenario: more is a typo (1-100000000 ran out of memory)


def parse_seeds(text):
    """'2-12', '2,5,7-9' -> the seeds in ascending order, each once; '' or 'none' -> []. At most MAX_SEEDS.
    Raises ValueError on anything else."""
    text = text.strip()
    if text.lower() in ("", "none"):
        return []
    seeds = set()
    for part in text.split(","):
        match = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", part)
        if not match:
            raise ValueError("'%s' is not a seed or a range of seeds (e.g. 2-12 or 2,5,7-9)" % part.strip())
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        if last < first:
            raise ValueError("'%s': the range ends before it starts" % part.strip())
        if last - first + 1 + len(seeds) > MAX_SEEDS:
            raise ValueError("more than %d seeds" % MAX_SEEDS)
        seeds.update(range(first, last + 1))
    return sorted(seeds)


def seed_label(seeds):
    """[1, 2, 3, 5] -> '1-3, 5'."""
    parts, start = [], None
    for i, seed in enumerate(seeds):
        if start is None:
            start = seed
        if i + 1 == len(seeds) or seeds[i + 1] != seed + 1:
            parts.append(str(start) if start == seed else "%d-%d" % (start, seed))
            start = None
    return ", ".join(parts)


# Every candidate of the cross-validation runs with the calibration off, so that the margin confidence c is
# what comes out; cross_validate fits the calibration sigma(offset + slope * c) on the training folds and
# scores it on the held-out one.
RAW_CONFIDENCE = "calibration_slope=0"


def parse_candidates(text):
    """The candidates file of the cross-validation: 'name: a=1 b=2' lines (# comments, blank lines skipped)
    -> [(name, [assignments])]; 'defaults' (no assignments) always first. Raises ValueError on a malformed
    line or a repeated name."""
    candidates = [("defaults", [])]
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        name, sep, rest = line.partition(":")
        name = name.strip()
        if not sep or not name or " " in name:
            raise ValueError("candidates line %d: expected 'name: name=value ...', got '%s'" % (number, line))
        assignments = rest.split()
        bad = [a for a in assignments if "=" not in a or a.startswith("=")]
        if bad:
            raise ValueError("candidates line %d: '%s' is not name=value" % (number, bad[0]))
        if any(name == c[0] for c in candidates):
            if name == "defaults" and not assignments:
                continue
            raise ValueError("candidates line %d: the name '%s' is used twice" % (number, name))
        candidates.append((name, assignments))
    return candidates


def set_arguments(assignments):
    """localize_offline's --set arguments for a candidate, the calibration off."""
    command = []
    for assignment in list(assignments) + [RAW_CONFIDENCE]:
        command += ["--set", assignment]
    return command


def check_candidates(binary, candidates):
    """Refuses a candidate localize_offline would refuse, before anything runs (it was found at its first run,
    after the folds were made and the candidates before it had run): EvaluationError naming the candidate."""
    for name, assignments in candidates:
        try:
            run([binary, "--check-params", "--method", "dtw"] + set_arguments(assignments))
        except EvaluationError as e:
            raise EvaluationError("candidate %s: %s" % (name, e))
