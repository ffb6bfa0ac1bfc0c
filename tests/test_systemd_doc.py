"""systemd/README.md, the unit and docs/operations.md say what a new operator needs, consistently (issue 52, finding 11).

Each test is one gap the issue found: the state path of ``status`` run by hand, the
checks to run after installing, ``[kafka] assignment = "manual"``, a credential the
code reads but the unit does not mention, how observers get the plans, directory
modes against the unit's ``StateDirectoryMode``, a hard-coded Python version, and
secrets typed on a command line.
"""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
README = (REPO / "systemd" / "README.md").read_text()
UNIT = (REPO / "systemd" / "mushrooms.service").read_text()
OPS = (REPO / "docs" / "operations.md").read_text()
CREDENTIALS = (REPO / "mushrooms" / "daemon" / "credentials.py").read_text()


def _shell_blocks(text: str) -> str:
    return "\n".join(re.findall(r"```(?:sh|bash|console)?\n(.*?)```", text, re.DOTALL))


def test_every_credential_the_code_reads_has_a_load_credential_line_in_the_unit() -> None:
    names = set(re.findall(r'_lookup\("([a-z_]+)"', CREDENTIALS)) | set(re.findall(r'_token\("([a-z_]+)"', CREDENTIALS))
    names |= set(re.findall(r'_secret\("([a-z_]+)"', CREDENTIALS))
    assert {"gcn_client_id", "gcn_client_secret", "submit_token", "notify_url"} <= names, names
    for name in names:
        assert re.search(rf"^#?LoadCredential={name}:/etc/mushrooms/{name}$", UNIT, re.MULTILINE), name
        assert name in README, name


def test_the_state_directory_mode_in_the_readme_is_the_units() -> None:
    mode = re.search(r"^StateDirectoryMode=(\d+)$", UNIT, re.MULTILINE).group(1)
    assert f"`/var/lib/mushrooms` is {mode}" in README, "the README must say the unit's mode of the state directory"
    for wrong in ("directories 0700 (", "service's directories 0700"):
        assert wrong not in README


def test_no_python_version_is_hard_coded() -> None:
    for text in (README, UNIT):
        assert not re.search(r"python3\.\d+", text)
    assert "requires-python" in README or "Python 3.11 or newer" in README


def test_no_secret_is_typed_on_a_command_line() -> None:
    shell = _shell_blocks(README)
    assert not re.search(r"printf %s \"YOUR", shell), "a secret in an argument lands in the shell history"
    assert "read -rs" in shell and "systemd-creds encrypt" in shell
    for var in ("MUSHROOMS_SUBMIT_TOKEN=...", "MUSHROOMS_NOTIFY_URL=..."):
        assert f"$ {var}" not in OPS, var


def test_the_usual_installation_uses_manual_assignment() -> None:
    assert 'assignment = "manual"' in README


def test_status_by_hand_says_the_state_path_and_the_user() -> None:
    assert "sudo -u mushrooms" in README and "STATE_DIRECTORY=/var/lib/mushrooms" in README
    assert re.search(r"mushrooms status --config /etc/mushrooms/config\.toml", README)
    assert "relative" in OPS and "STATE_DIRECTORY" in OPS


def test_preflight_and_rehearse_follow_the_installation() -> None:
    install = README.split("## Operate")[0]
    assert "mushrooms preflight" in install and "mushrooms rehearse" in install
    assert "systemd-run" in install and "LoadCredential=gcn_client_secret" in install
    assert "## Before an event: `mushrooms preflight`" in OPS


def test_observers_are_told_how_to_get_the_plans() -> None:
    assert "## Plans for the observers" in README
    section = README.split("## Plans for the observers")[1]
    assert "ReadWritePaths=" in section and "group_readable" in section and 'sink = "kafka"' in section
