"""FabrickatorWorkbench.deps outside FreeCAD: the install's commands, its progress read from
pip's lines, its failure messages and the interpreter it builds the venv with.

(The install itself, in a clean FreeCAD user folder, is tested in freecadcmd and in the
GUI: tests/app/TestFabrickatorInstall.py, tests/gui/TestFabrickatorInstallGui.py.)
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from FabrickatorWorkbench import deps


def test_the_install_commands_build_the_venv_then_pip_installs_the_pins(tmp_path, monkeypatch):
    monkeypatch.setenv(deps.VENV_ENV, str(tmp_path / "venv"))
    venv, pip = deps.install_commands("/usr/bin/python3.11")
    assert venv == ["/usr/bin/python3.11", "-m", "venv", "--clear", str(tmp_path / "venv")]
    assert pip[:4] == [str(tmp_path / "venv" / "bin" / "python"), "-m", "pip", "install"]
    assert pip[-2:] == ["-r", deps.REQUIREMENTS]
    command = deps.fix_command("/usr/bin/python3.11")
    assert command == (f"/usr/bin/python3.11 -m venv --clear {tmp_path}/venv && {tmp_path}/venv/bin/python "
                       f"-m pip install --disable-pip-version-check --progress-bar off -r {deps.REQUIREMENTS}")
    assert deps.site_packages() == str(tmp_path / "venv" / "lib" / f"python{sys.version_info[0]}."
                                       f"{sys.version_info[1]}" / "site-packages")


def test_a_path_with_spaces_is_quoted_for_the_shell(tmp_path, monkeypatch):
    monkeypatch.setenv(deps.VENV_ENV, str(tmp_path / "my venv"))
    command = deps.fix_command("/opt/Free CAD/bin/python3")
    assert command.startswith(f"'/opt/Free CAD/bin/python3' -m venv --clear '{tmp_path}/my venv' && ")


def test_the_interpreter_is_this_python_when_run_by_python():
    found = deps.base_interpreter()
    assert found is not None
    run = subprocess.run([found, "-c", "import sys; print(sys.version)"], capture_output=True, text=True)
    assert run.stdout.split()[0] == sys.version.split()[0]


def test_the_install_environment_drops_freecads_module_path():
    env = deps.install_env({"PATH": "/usr/bin", "PYTHONPATH": "/usr/lib/freecad/lib", "PIP_USER": "1",
                            "PIP_FIND_LINKS": "/opt/wheels"})
    assert env == {"PATH": "/usr/bin", "PIP_FIND_LINKS": "/opt/wheels"}


PIP_LINES = """Collecting attrs==26.1.0 (from -r requirements.txt (line 1))
  Downloading attrs-26.1.0-py3-none-any.whl (63 kB)
Collecting cadquery==2.6.1 (from -r requirements.txt (line 3))
  Using cached cadquery-2.6.1-py3-none-any.whl (179 kB)
Collecting vtk==9.3.1 (from cadquery==2.6.1)
Processing /opt/pypi/files/cycler-0.12.1-py3-none-any.whl
Installing collected packages: attrs, cadquery, vtk, cycler
Successfully installed attrs-26.1.0 cadquery-2.6.1 cycler-0.12.1 vtk-9.3.1
""".splitlines()


def test_progress_grows_with_pips_lines_and_is_busy_while_it_unpacks(tmp_path):
    requirements = tmp_path / "requirements.txt"
    requirements.write_text("# pins\nattrs==26.1.0\ncadquery==2.6.1\n\ncycler==0.12.1\nnumpy==2.1.3\n")
    meter = deps.PipProgress(str(requirements))
    assert meter.total == 4 and meter.text == "Building the virtual environment"
    assert meter.started_pip() == deps.PipProgress.VENV_SHARE
    seen = [(meter.feed(line), meter.text) for line in PIP_LINES]
    fractions = [f for f, _ in seen]
    step = (deps.PipProgress.INSTALL_FROM - deps.PipProgress.VENV_SHARE) / 4
    assert fractions[:6] == pytest.approx([0.05 + step, 0.05 + step, 0.05 + 2 * step, 0.05 + 2 * step,
                                           0.05 + 3 * step, 0.05 + 3 * step])
    assert fractions[6] is None and seen[6][1] == "Installing 3 packages (this takes a while)"
    assert fractions[7] == 1.0 and seen[7][1] == "Installed"
    assert seen[1][1] == "Downloading attrs-26.1.0-py3-none-any.whl (63 kB)"
    # more packages collected than pinned (unpinned dependencies): the share stops at INSTALL_FROM
    for _ in range(10):
        meter.feed("Collecting more==1.0")
    assert meter.fraction == deps.PipProgress.INSTALL_FROM


OFFLINE = """Looking in indexes: https://pypi.org/simple
WARNING: Retrying (Retry(total=4, connect=None, read=None, redirect=None, status=None)) after connection \
broken by 'NewConnectionError('<pip._vendor.urllib3.connection.HTTPSConnection object>: Failed to establish \
a new connection: [Errno -3] Temporary failure in name resolution')': /simple/attrs/
ERROR: Could not find a version that satisfies the requirement attrs==26.1.0 (from versions: none)
ERROR: No matching distribution found for attrs==26.1.0""".splitlines()


def test_no_network_is_said_with_pips_error_and_the_command(tmp_path, monkeypatch):
    monkeypatch.setenv(deps.VENV_ENV, str(tmp_path / "venv"))
    message = deps.failure_message(OFFLINE, 1, 1)
    assert message.startswith("Fabrickator could not download its Python packages: no network, or the package "
                              "index cannot be reached (pip: No matching distribution found for attrs==26.1.0). ")
    assert message.endswith(f"run in a terminal: {deps.fix_command()}")
    assert "\n" not in message


def test_other_failures_name_the_step_and_the_fix(tmp_path, monkeypatch):
    monkeypatch.setenv(deps.VENV_ENV, str(tmp_path / "venv"))
    ensurepip = ["The virtual environment was not successfully created because ensurepip is not",
                 "available.  On Debian/Ubuntu systems, you need to install the python3-venv package"]
    assert "install the package python3-venv" in deps.failure_message(ensurepip, 1, 0)
    disk = deps.failure_message(["Collecting numpy==2.1.3", "ERROR: Could not install packages due to an "
                                 "OSError: [Errno 28] No space left on device"], 1, 1)
    assert disk.startswith("Fabrickator could not install its Python packages (pip: Could not install packages "
                           "due to an OSError: [Errno 28] No space left on device). ")
    assert deps.failure_message([], -9, 1).startswith("Fabrickator could not install its Python packages "
                                                      "(pip: exit status -9)")


def test_needs_install_says_why(tmp_path, monkeypatch):
    monkeypatch.setenv(deps.VENV_ENV, str(tmp_path / "venv"))
    monkeypatch.setattr(deps, "REQUIRED", ("numpy", "no_such_package_fabrickator"))
    assert deps.needs_install() == (f"no_such_package_fabrickator cannot be imported: {deps.site_packages()} "
                                    f"is missing")
    monkeypatch.setattr(deps, "REQUIRED", ("numpy",))
    assert deps.needs_install() is None


def test_a_venv_built_after_another_numpy_was_loaded_needs_a_restart_not_a_new_install(tmp_path, monkeypatch,
                                                                                      capsys):
    # this process's numpy (the developer venv's) stands for the numpy FreeCAD loaded before the install
    import numpy

    monkeypatch.setenv(deps.VENV_ENV, str(tmp_path / "venv"))
    monkeypatch.setattr(deps, "REQUIRED", ("numpy", "no_such_package_fabrickator"))
    monkeypatch.setattr(sys, "path", list(sys.path))
    holder = type(sys)("fabrickator_numpy_holder")
    holder.np = numpy
    monkeypatch.setitem(sys.modules, holder.__name__, holder)
    packages = tmp_path / "venv" / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    packages.mkdir(parents=True)
    # half built (pip did not finish: no stamp): install again
    assert deps.needs_install() == f"no_such_package_fabrickator cannot be imported: {packages} lacks them"
    assert not deps.installed_not_in_use()
    deps.write_stamp()
    assert deps.installed_not_in_use()
    assert deps.needs_install() is None
    clash = deps.numpy_clash()
    assert clash.startswith(f"numpy {numpy.__version__} from {os.path.dirname(os.path.dirname(numpy.__file__))} "
                            f"was loaded in this FreeCAD before Fabrickator could put its own first, used by ")
    assert holder.__name__ in deps.numpy_importers(limit=len(sys.modules))
    assert deps.activate(["numpy"]) == f"restart FreeCAD to use them ({clash})"
    assert str(packages) not in sys.path
    capsys.readouterr()
    assert not deps.check("Legofy")
    said = capsys.readouterr().err
    assert f"Fabrickator: Legofy needs the Python packages installed in {tmp_path / 'venv'}, which this " \
           f"FreeCAD cannot use yet ({clash}: restart FreeCAD" in said
    assert "Install Python packages..." not in said
    # the add-on was updated: requirements.txt newer than the stamp asks for the install again
    os.utime(os.path.join(tmp_path, "venv", deps.STAMP), (0, 0))
    assert deps.needs_install() == f"{deps.REQUIREMENTS} changed since {tmp_path / 'venv'} was built"


def test_the_venvs_own_numpy_is_no_clash(monkeypatch):
    import numpy

    monkeypatch.setenv(deps.VENV_ENV, os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(
        os.path.dirname(numpy.__file__))))))
    assert deps.site_packages() == os.path.dirname(os.path.dirname(numpy.__file__))
    assert deps.numpy_clash() is None
    assert deps.problem() is None
