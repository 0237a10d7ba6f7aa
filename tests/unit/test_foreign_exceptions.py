"""Bad input never reaches the user as a foreign exception: one test per class of bad input that used to.

A table parameter edited in place (numpy's ``ValueError: assignment destination is read-only``), a model with
a lambda signal pickled (``PicklingError``), a result written into a folder that does not exist
(``FileNotFoundError``), a user's law that returns a string (``NameError: name 'x' is not defined``) or raises
its own exception (passed through with no device named), a ``Param`` with an unknown check (accepted silently).
"""

import math
import pickle
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import regmech as rm
from regmech.components import Clutch, Fixed, Inertia, Torque, TwoFlangeCompliant
from regmech.components.laws import FrictionLaw
from regmech.library import coupled_clutches


# ------------------------------------------------------------------------------------ tables edited in place
def test_a_table_edited_in_place_is_a_parameter_error_naming_the_device():
    m = coupled_clutches()
    m["clutch1"].mu_table = [[0.0, 0.5], [10.0, 0.4]]
    with pytest.raises(rm.ParameterError, match=r"Clutch 'clutch1': parameter 'mu_table' is read-only.*assign"):
        m["clutch1"].mu_table[:, 1] = 0.3
    with pytest.raises(rm.ParameterError, match=r"Clutch 'clutch1': parameter 'mu_table'"):
        table = m["clutch1"].mu_table
        table *= 2.0
    # what the message says to do takes effect
    table = m["clutch1"].mu_table.copy()
    table[1, 1] = 0.3
    m["clutch1"].mu_table = table
    assert m["clutch1"]._mu(10.0)[0] == pytest.approx(0.3)
    # arithmetic with the table gives plain arrays that can be edited
    scaled = m["clutch1"].mu_table * 2.0
    scaled[0, 0] = 1.0
    assert type(scaled) is np.ndarray


def test_a_frozen_table_pickles_and_stays_read_only():
    c = Clutch("c", fn_max=1.0, mu_table=[[0.0, 0.5], [10.0, 0.4]])
    back = pickle.loads(pickle.dumps(c))
    with pytest.raises(rm.ParameterError, match="Clutch 'c': parameter 'mu_table'"):
        back.mu_table[0, 1] = 0.1


# ------------------------------------------------------------------------------------------- pickled lambdas
def _driven(tau):
    m = rm.Model("driven")
    J = m.add(Inertia("J", J=0.5, phi0=0.0, w0=0.0))
    drive = m.add(Torque("drive", tau=tau))
    m.connect(drive.flange, J.flange_a)
    return m


def _closure():
    gain = 2.0

    def tau(t):
        return gain * np.sin(3.0 * t)
    return tau


@pytest.mark.parametrize("tau", [lambda t: 2.0 * math.sin(3.0 * t), _closure()])
def test_a_model_with_a_lambda_signal_pickles_and_runs_the_same(tau):
    m = _driven(tau)
    back = pickle.loads(pickle.dumps(m))
    a = m.simulate(0.5, dt_out=0.01, solver="ida", rtol=1e-8)
    b = back.simulate(0.5, dt_out=0.01, solver="ida", rtol=1e-8)
    np.testing.assert_array_equal(a["J.w"], b["J.w"])


def test_a_pickled_lambda_runs_in_a_fresh_interpreter(tmp_path):
    path = tmp_path / "model.pkl"
    path.write_bytes(pickle.dumps(_driven(lambda t: 2.0 * np.sin(3.0 * t))))
    code = textwrap.dedent(f"""
        import pickle
        m = pickle.loads(open({str(path)!r}, "rb").read())
        res = m.simulate(0.5, dt_out=0.01, solver="ida", rtol=1e-10)
        print(repr(float(res.final("J.w"))))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    # w(t) = int 2 sin(3 t) / 0.5 dt = 4 (1 - cos(3 t)) / 3
    assert float(out.stdout.strip()) == pytest.approx(4.0 * (1.0 - math.cos(1.5)) / 3.0, rel=1e-7)


def test_a_signal_that_cannot_be_pickled_is_named():
    lock = threading.Lock()
    m = _driven(lambda t, _lock=lock: 1.0)
    with pytest.raises(pickle.PicklingError, match=r"Torque 'drive': signal 'tau'.*cannot be pickled") as err:
        pickle.dumps(m)
    assert isinstance(err.value, rm.RegmechError)


# ------------------------------------------------------------------------------------- writing to no folder
def test_writing_a_result_into_a_missing_folder_names_it(tmp_path):
    res = _driven(1.0).simulate(0.1, dt_out=0.01)
    missing = tmp_path / "no_such_folder"
    with pytest.raises(rm.RegmechError, match=r"res.to_csv: cannot write .*the folder '.*no_such_folder' does not "
                                              r"exist"):
        res.to_csv(missing / "run.csv")
    with pytest.raises(rm.RegmechError, match=r"res.save: .*no_such_folder' does not exist"):
        res.save(missing / "run.mat")
    pytest.importorskip("matplotlib")
    with pytest.raises(rm.RegmechError, match=r"res.plot: .*no_such_folder' does not exist"):
        res.plot(path=missing / "run.png")


# ------------------------------------------------------------------------------------------------ user laws
class TextSpring(TwoFlangeCompliant):
    c = rm.Param(check="positive", unit="N m/rad")

    def law(self, rel, rel_dot):
        return "x"


class FailingSpring(TwoFlangeCompliant):
    c = rm.Param(check="positive", unit="N m/rad")

    def law(self, rel, rel_dot):
        raise KeyError("stiffness")


class StraySymbolSpring(TwoFlangeCompliant):
    c = rm.Param(check="positive", unit="N m/rad")

    def law(self, rel, rel_dot):
        import sympy
        return self.c * rel + sympy.Symbol("k") * rel_dot


def _sprung(cls):
    m = rm.Model("sprung")
    f = m.add(Fixed("f"))
    k = m.add(cls("spring", c=10.0))
    J = m.add(Inertia("J", J=1.0, phi0=0.1, w0=0.0))
    m.connect(f.flange, k.flange_a)
    m.connect(k.flange_b, J.flange_a)
    return m


@pytest.mark.parametrize("cls, what", [(TextSpring, "returned the string 'x'"),
                                       (FailingSpring, "KeyError: 'stiffness'"),
                                       (StraySymbolSpring, r"unknown symbol\(s\) \['k'\]")])
def test_a_users_device_law_that_is_no_expression_is_named(cls, what):
    with pytest.raises(rm.ModelError, match=rf"{cls.__name__} 'spring': .*{what}"):
        _sprung(cls).simulate(0.1)


class RaisingLaw(FrictionLaw):
    def mu(self, w_abs):
        return 0.4 / (w_abs - w_abs), 0.0


class TextLaw(FrictionLaw):
    def mu(self, w_abs):
        return "0.4", "none"


class NanLaw(FrictionLaw):
    def mu(self, w_abs):
        return float("nan"), 0.0


@pytest.mark.parametrize("law, what", [(RaisingLaw(), "raised ZeroDivisionError"), (TextLaw(), "raised ValueError"),
                                       (NanLaw(), r"returned \(nan, 0.0\)")])
def test_a_users_friction_law_that_fails_is_named_with_its_device(law, what):
    m = rm.Model("clutched")
    J1 = m.add(Inertia("J1", J=1.0, w0=10.0))
    c = m.add(Clutch("clutch", mu_law=law, fn_max=10.0, f_normalized=1.0))
    J2 = m.add(Inertia("J2", J=1.0, w0=0.0))
    m.connect(J1.flange_b, c.flange_a)
    m.connect(c.flange_b, J2.flange_a)
    with pytest.raises(rm.SimulationError, match=rf"Clutch 'clutch': mu_law {type(law).__name__}: mu\(.*{what}"):
        m.simulate(0.1)


# ---------------------------------------------------------------------------------------------- Param checks
@pytest.mark.parametrize("check, hint", [("wibble", "unknown check"), ("postive", "did you mean 'positive'")])
def test_a_param_with_an_unknown_check_is_refused(check, hint):
    with pytest.raises(rm.ParameterError, match=rf"Param\(check='{check}'\): .*{hint}"):
        rm.Param(check=check)
    with pytest.raises(rm.ParameterError, match="choices"):
        rm.Param("a", check="choice")
