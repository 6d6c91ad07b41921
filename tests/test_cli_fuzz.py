"""Bad input never crashes or hangs: every numeric option of every subcommand, given NaN, ±inf or an
empty value, is refused with one line naming it (exit status 2) within 5 s; zero, negative and huge
values either do the same or are valid; missing, unreadable and malformed files are refused the same
way. Work that valid input would start (a simulation, learning the primitives) is replaced by a
marker, so only the checks in front of it run."""

import argparse
import contextlib
import io
import signal

import pytest

from robot_ctrl import cli

INVALID = ("nan", "inf", "-inf", "")
EDGE = ("-1", "0", "1e9")
NEEDS = {("synth",): ["--distance", "1.5"], ("crowd", "run"): ["--k", "1"], ("crowd", "certify"): ["--md", "1"],
         ("report",): ["/nonexistent-run"],
         ("campaign",): ["--n", "2"]}


class Started(Exception):
    """Valid input reached the work it starts."""


class TooSlow(Exception):
    pass


def leaves(parser, prefix=()):
    subparsers = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subparsers:
        yield prefix, parser
    for action in subparsers:
        for name, sub in action.choices.items():
            yield from leaves(sub, (*prefix, name))


def numeric_options():
    for prefix, parser in leaves(cli.build_parser()):
        for action in parser._actions:
            if action.option_strings and action.type in (int, float):
                yield prefix, action.option_strings[0]


def run(argv):
    """(exit status or 'started', stderr) of ``robot-ctrl argv``, within 5 s."""
    err = io.StringIO()
    previous = signal.signal(signal.SIGALRM, lambda *_: (_ for _ in ()).throw(TooSlow()))
    signal.alarm(5)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                return cli.main(argv), err.getvalue()
            except SystemExit as exc:
                return exc.code, err.getvalue()
            except Started:
                return "started", err.getvalue()
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@pytest.fixture
def no_work(monkeypatch):
    import robot_ctrl.backends as hardware
    import robot_ctrl.crowd.audit as audit
    import robot_ctrl.crowd.experiments as experiments
    import robot_ctrl.eval.campaigns.campaign_backends as campaign_backends
    import robot_ctrl.scenarios.group_walk as group_walk
    import robot_ctrl.synthesis.demonstrations as demonstrations
    import robot_ctrl.synthesis.learned as synthesis

    def start(*args, **kwargs):
        raise Started()

    for module, name in ((hardware, "open_hardware"), (hardware, "open_group_hardware"),
                         (group_walk, "open_group_hardware"), (experiments, "run_group"),
                         (experiments, "rate_slopes"), (audit, "audit"), (synthesis, "load_primitives"),
                         (demonstrations, "generate_demonstrations"), (campaign_backends, "open_backend")):
        monkeypatch.setattr(module, name, start)


def one_error_line(stderr):
    lines = stderr.strip().splitlines()
    return len(lines) >= 1 and lines[-1].startswith(("robot-ctrl: error:", "robot-ctrl ")) and "Traceback" not in stderr


@pytest.mark.parametrize("prefix,option", list(numeric_options()), ids=lambda v: " ".join(v) if isinstance(v, tuple) else v)
def test_every_numeric_option_refuses_bad_values(prefix, option, no_work):
    for value in INVALID + EDGE:
        status, stderr = run([*prefix, *NEEDS.get(prefix, []), option, value])
        if value in INVALID or status == 2:
            assert status == 2 and one_error_line(stderr), (prefix, option, value, status, stderr[-300:])
            if value in INVALID:  # named: --turn-deg → turn, --mass-scale → mass
                word = option.lstrip("-").split("-")[0]
                assert word in stderr.lower() or "invalid" in stderr, (prefix, option, value, stderr)
        else:
            assert status in (0, 1, "started"), (prefix, option, value, status, stderr[-300:])


def test_missing_unreadable_and_malformed_files_are_refused(tmp_path):
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("backend: [mit_can\n")
    not_a_matrix = tmp_path / "words.txt"
    not_a_matrix.write_text("a b\nc d\n")
    cases = [
        ["walk", "--distance", "1", "--hw", "mit-can-emulated", "--bus-config", str(bad_yaml)],
        ["balance", "--hw", "dynamixel-emulated", "--bus-config", str(tmp_path / "missing.yaml")],
        ["crowd", "certify", "--laplacian", str(tmp_path / "missing.txt"), "--k", "1"],
        ["crowd", "certify", "--adjacency", str(not_a_matrix), "--k", "1"],
        ["crowd", "certify", "--g-profile", str(tmp_path), "--k", "1"],  # a folder, not a file
        ["synth", "--distance", "1.5", "--dataset", str(tmp_path / "missing.npz")],
        ["report", str(tmp_path / "no-run")],
        ["walk", "--robot", str(bad_yaml), "--distance", "1"],
    ]
    for argv in cases:
        status, stderr = run(argv)
        assert status == 2 and one_error_line(stderr), (argv, status, stderr[-400:])
