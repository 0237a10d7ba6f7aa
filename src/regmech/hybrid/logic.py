"""The mode logic of friction and loss elements: iterating the modes at an event to a consistent set.

As MSL does it (``Modelica.Mechanics.Rotational.Interfaces.PartialFriction``):

* sliding -> Stuck when ``w_rel`` reaches zero (root of ``mode * w_rel``, decreasing); the new
  Stuck mode is checked only in the next iteration;
* Stuck -> Forward/Backward when the holding torque leaves ``[-tau0_max, tau0_max]`` (root of
  ``tau0_max - |lam|``); after break-away the kinetic torque at zero speed is ``tau0 < tau0_max``,
  so the device accelerates away (hysteresis, no chattering);
* any mode -> Free when the normal force drops to <= 0; Free -> sliding by the sign of ``w_rel``
  when it becomes positive (Stuck if ``w_rel`` is 0);
* the holding torques of *all* stuck devices come from one KKT solve (``holding``), and the logic
  iterates until no mode changes.
"""

from __future__ import annotations

import numpy as np

from .._numbers import abs_max
from ..errors import SimulationError, StructureError
from ..modes import BACKWARD, FORWARD, FREE, HELD, STUCK
from .gears import gear_first_step
from .impacts import RELEASE_TOL


#: a stuck device within this fraction of its capacity is probed a moment later (``_probe_breakaways``)
PROBE_EDGE = 1e-6
#: the probe's time step, relative to max(1, |t|) [s]
PROBE_DT = 1e-7
#: a stuck lossy gear whose loss torque is past its limit by no more than this fraction of its torques is at a tie:
#: its load a moment later decides (``_gear_tie_probe``)
GEAR_TIE = 1e-9


class ModeLogic:
    """``settle``: the event iteration of a ``FrictionSet`` (mixin)."""

    def settle(self, t, state, modes, crossed=None, initial=False):
        """Iterate the mode logic at time t to a consistent set; returns (y, yp, modes, changes).

        ``changes``: ``(device name, old, new, kind)`` per change, ``kind`` "mode" (old and new
        mode) or "driving side" (a lossy gear rolling on with power now flowing the other way;
        old and new are the driving flange, ``LossyGear.driving_flange``).
        """
        c = self.c
        self._law_memo = {}           # ``_law``: the laws of devices without inputs at this instant
        if initial:
            self.quadrant[:] = 1      # a fresh start decides the driving sides from the state alone
        side_old = [d.driving_flange(m0, q) if d.coupled else 0
                    for d, m0, q in zip(self.devices, np.asarray(modes, dtype=int), self.quadrant)]
        if state is None:
            state = c.initial_y(t, np.full(self.mf, FREE))
        old = np.array(modes, dtype=int)
        lam_rate = state[1][c.ilam[self.offset:]]        # d lam/dt at the event (IDA's interpolant)
        stop_side_old = self.stop_side.copy()      # hard stops' limits before this event
        self._impact_log = []
        y, yp, new, scale, view = self._settle_once(t, state, old, crossed, initial, lam_rate)
        # The modes settled here must be what the logic finds again at this instant with nothing crossed: a device
        # left sliding at zero slip, held by others, is re-stuck at the next event whatever it is (fuzz seed 102's
        # rule), and with several holders the outcome then differed (fuzz seed 10169: a bearing re-stuck with
        # its static capacity at one event broke away 1.7 ms later under DOP853, at once under IDA, whose round-off
        # crossing of a slip of 1e-97 gave the extra event: 1 % of the range apart). So the logic runs again from
        # its own answer until that changes nothing (bounded; a pair of answers taking turns keeps the later one).
        rerun = False
        for _ in range(3):
            if not self._held_sliding(view, new, scale):
                break           # the usual case: nothing the logic would read differently (no second run)
            rerun = True
            y2, yp2, again, scale, view2 = self._settle_once(t, (y, yp), new, None, False, lam_rate)
            if np.array_equal(again, new):
                break
            y, yp, new, view = y2, yp2, again, view2
        self._check_sliding_sides(t, view, new, scale)
        if rerun:       # else ``_settle_once`` found them for this very (y, yp, new, scale)
            self._relief = self._relief_events(t, y, yp, new, scale, view)
        self._ev_key = None
        self._small_for = self._at_segment = None      # the event functions' plans belong to a segment
        q = self.q_all(t, y) if self.has_inputs else None
        self.engaged = np.array([self._law("normal_force", j, q, t, False) > 0 for j in range(self.mf)])
        changes = list(self._impact_log)     # impacts of hard stops first (``impacts``), with their losses
        self._impact_log = []
        if self._stops:
            lam_now = y[c.ilam]
            self._stop_tol[:] = RELEASE_TOL * max(1.0, abs_max(lam_now))
        if not initial:
            for j, dev in enumerate(self.devices):
                if j in self._stop_set:
                    was = dev.contact_state(old[j], stop_side_old[j])
                    now = dev.contact_state(new[j], self.stop_side[j])
                    if was != now:
                        changes.append((dev.name, was, now, "contact"))
                    continue
                if old[j] != new[j]:
                    changes.append((dev.name, int(old[j]), int(new[j]), "mode"))
                if dev.coupled and old[j] in (FORWARD, BACKWARD) and new[j] in (FORWARD, BACKWARD):
                    side = dev.driving_flange(new[j], self.quadrant[j])
                    if side != side_old[j]:
                        changes.append((dev.name, side_old[j], side, "driving side"))
        return y, yp, new, changes

    def _settle_once(self, t, state, old, crossed, initial, lam_rate):
        """One run of the mode logic from ``old`` at ``(t, state)``: ``(y, yp, new, scale)``, the restart state in
        the new modes (``settle`` repeats it to a fixed point)."""
        c = self.c
        left = False   # the new segment: right limits
        y0, yp0 = state
        x, v, a, lam, z = c.unpack(y0, yp0)
        q = self.q_from(t, x, v, z)     # inputs of the laws from the state (None without any)
        new = old.copy()
        # 0. hard stops first: a limit reached is an impact (the speeds jump, ``impacts``), a holding contact whose
        #    release function crossed lets go; the other devices then decide on the speeds after the impulse
        self._modes_now = old
        crossed = np.zeros(self.n_events) if crossed is None else np.asarray(crossed)
        impacted = False
        if self._stops:
            n_log = len(self._impact_log)
            for j in self._stops:
                new[j], v = self._stop_step(j, self.devices[j], int(old[j]), x, v, z, crossed, initial, t, 1e-9 *
                                            max(1.0, abs_max(v)))
            impacted = len(self._impact_log) > n_log
        w = self.w_rel(v)
        arel = self.w_rel(a)
        scale = 1e-9 * max(1.0, abs_max(v))
        # devices sliding at zero speed while another one holds the motion (see _relief_events):
        # their speed is zero by the holder's constraint, so its round-off sign says nothing;
        # only their relief event, or their holder letting go (``_still_relieved``), changes them
        relief = set() if initial else self._still_relieved(new, crossed)
        for j in relief:
            w[j] = 0.0
        # round-off of the relative accelerations (a device at rest, held by others, has |a_rel| below it)
        a_tol = 1e-9 * max(1.0, abs_max(a))
        # 1. engagement and the crossings that were found
        for j, dev in enumerate(self.devices):
            if j in self._stop_set:
                continue
            engaged = self._law("normal_force", j, q, t, left) > 0
            if dev.coupled:
                new[j] = gear_first_step(dev, int(old[j]), w[j], crossed[2 * j] != 0, crossed[2 * j + 1] != 0,
                                         initial, scale, arel[j], impacted,
                                         at_rest=abs(arel[j]) <= a_tol and j not in relief)
                if old[j] == STUCK and new[j] != STUCK and \
                        self._gear_at_tie(dev, new[j], lam[self.offset + j], lam[self.coupled[j]]):
                    # its break-away function crossed at a tie: an idle gear with no load has its loss torque and
                    # both limits at zero, and the function's round-off crossed (calibration seed 8031: a lossy
                    # planetary at rest broke away Backward, stopped at once, and did so 50 times within 1 us at
                    # t = 2e-7 s, ChatteringError). It stays stuck, and the break-away test of the passes below,
                    # on the torques solved there, decides (probing the load a moment later at a tie)
                    new[j] = STUCK
                if old[j] in (FORWARD, BACKWARD) and new[j] == old[j] and crossed[2 * j + 1] != 0:
                    self.quadrant[j] = -self.quadrant[j]   # the driving side changed (checked in step 2)
                continue
            if dev.one_way:
                new[j] = self._one_way_step(dev, j, old[j], engaged, w[j], lam[self.offset + j],
                                            crossed[2 * j] != 0, initial, scale, t)
                continue
            if not engaged:
                new[j] = FREE
            elif initial or old[j] == FREE:
                # engaging (or starting) within round-off of zero slip: Stuck, and the holding-torque check
                # below decides whether and which way it breaks away; a direction taken from the round-off
                # sign of w_rel gave a guard (mode * w_rel) starting at zero, which IDA's root finding leaves
                # inactive, so the slip passed zero unseen (a clutch re-engaged by a Sine normal force)
                new[j] = FORWARD if w[j] > scale else BACKWARD if w[j] < -scale else STUCK
            elif old[j] == HELD:
                # its holders kept it at zero speed (to round-off): it holds again unless it has moved
                new[j] = FORWARD if w[j] > scale else BACKWARD if w[j] < -scale else STUCK
            elif impacted and old[j] in (FORWARD, BACKWARD) and old[j] * w[j] < -scale:
                # an impact's impulse reversed its slip: it slides the other way now
                new[j] = -old[j]
            elif old[j] in (FORWARD, BACKWARD) and (crossed[2 * j] != 0 or
                                                     (abs(w[j]) <= scale and
                                                      (old[j] * arel[j] < -a_tol or
                                                       (abs(arel[j]) <= a_tol and j not in relief)))):
                # found by the root finder, or within round-off of zero slip and not leaving it in its own
                # direction, decided by the relative acceleration beyond its round-off (the signs of a
                # w_rel and an a_rel of 1e-20 are noise): pushed back or still approaching (several
                # devices reaching zero slip at one instant; w_rel = 0.0 exactly must not keep the mode:
                # fuzz seed 37), or at rest, held at zero slip by other devices: at rest it has its
                # static capacity, and the holding-torque check below decides whether it breaks away
                # (fuzz seed 102: a bearing held at rest through a planetary by a brake kept sliding
                # with its kinetic torque, or stuck, by the round-off sign of an a_rel of 6e-18, when the
                # brake let go). A device that has just broken away has w_rel ~ 0 too, but accelerates
                # away on its own side; one whose relief event is set (``_relief_events``) changes only
                # by that event or by an event of its holder.
                new[j] = STUCK
            elif old[j] == STUCK and crossed[2 * j] != 0:
                # the root of tau0_max - |lam| was located (to round-off) on either side of zero:
                # the crossing itself decides, so the restart is where the condition has flipped
                new[j] = FORWARD if lam[self.offset + j] > 0 else BACKWARD
        self._flips = set()
        # 2. stuck devices: holding torques of the whole stuck set from one KKT solve; every device
        #    beyond its tau0_max breaks away at once (as in one Modelica event iteration), then repeat
        known = None
        probed = False
        # devices that left rest at this event (``_tie_break_holds``): a break-away at a tie is judged by the motion
        # a moment later, once; ``tie_held`` are those that judgement kept stuck (no lenient break-away again)
        broke = {j for j in range(self.mf) if old[j] in (STUCK, HELD) and new[j] in (FORWARD, BACKWARD)}
        tie_held = set()
        passes = 4 * self.mf + 4
        changed_in = np.zeros(self.mf, int)     # passes in the second half in which each device changed
        for k in range(passes):
            before = new.copy()
            try:
                # locking can conflict like the accelerations can: two stuck devices and a motion source on
                # one loop (a brake reaching zero slip on a mass a stuck clutch ties to a Speed source)
                v = self._lock_velocities(t, x, v, new, old)
                a, lam, dz = c.accelerations(t, x, v, z, new)
                known = (a, lam, dz)
            except StructureError as exc:
                if not self._share_redundant(t, x, v, z, new):
                    if initial:
                        raise
                    # not a start value the user gave: the modes reached at this event contradict the model
                    raise SimulationError(
                        f"stick/slip logic at t={t:.9g} s: the friction modes reached at this event admit no "
                        f"consistent motion ({str(exc).split('. Fix:')[0]}). This is a gap in regmech's mode "
                        f"logic: please report it with the model; a compliance (an elastic Shaft) between the "
                        f"stuck devices and the motion source avoids it") from exc
                continue
            lam_f = lam[self.offset:]
            q = self.q_from(t, x, v, z)          # a command may read the speeds just locked
            noise = self._load_noise(x, lam)
            changed = False
            for j, dev in enumerate(self.devices):
                if dev.coupled:
                    if new[j] == STUCK:
                        d = dev.breakaway(lam_f[j], lam[self.coupled[j]])
                        if d and self._gear_at_tie(dev, d, lam_f[j], lam[self.coupled[j]]):
                            # beyond its limit by round-off only: where the load goes decides (as for a friction
                            # device at its capacity), read a moment later; after another change in this pass the
                            # torques are stale and the next pass decides
                            d = 0 if changed else self._gear_tie_probe(j, dev, d, t, x, v, z, new, a, dz)
                        if d:
                            new[j] = d
                            changed = True
                    elif new[j] in (FORWARD, BACKWARD) and not changed and \
                            self._fix_quadrant(j, dev, new, t, x, v, z, a, lam, dz):
                        # (only while ``new`` is still the set this pass's torques were solved with: after an
                        # earlier device of the pass changed, the torques are stale, and a flip decided on
                        # them was booked under the changed set, which barred the flip back: fuzz seeds 353
                        # and 454, a clutch breaking away in the same pass, the gear rolling on the wrong
                        # side and supplying power until the next event)
                        changed = True
                    continue
                if new[j] != STUCK:
                    continue
                if j in self._stop_set:
                    if self._stop_release(t, x, j, lam_f[j], new):
                        new[j] = FREE
                        changed = True
                    continue
                if abs(lam_f[j]) <= noise:
                    continue        # a load within the round-off of the forces is no load (``_load_noise``)
                qj = None if q is None else q[j]
                tau0, tau0_max = self._law("capacities", j, q, t, left)
                # a load within round-off of the capacity and still rising breaks away with the others
                # (symmetric devices, e.g. two wheels on one open differential, reach it together)
                tie = 1e-9 * tau0_max
                # at a tie the load breaks away when it rises faster than the capacity: a capacity falling under a
                # steady load (a normal force passing its minimum) is a break-away too (fuzz seed 30252: a brake
                # whose crossing was found broke away, was re-stuck by settle's second run, whose test read the
                # load's rate alone, and held 28.9 N m with a capacity falling to 8.5 N m: a silently wrong run)
                at_tie = abs(abs(lam_f[j]) - tau0_max) <= tie
                cap_rate = self._capacity_rate(dev, qj, t, left, tau0_max) if at_tie else 0.0
                lenient = j not in tie_held
                if lam_f[j] > tau0_max * (1 + 1e-12) or \
                        (lenient and lam_f[j] > tau0_max - tie and lam_rate[j] > cap_rate):
                    new[j] = self._slide_direction(dev, qj, t, left, 1)
                    changed = True
                elif (lam_f[j] < -tau0_max * (1 + 1e-12) or
                      (lenient and lam_f[j] < -tau0_max + tie and lam_rate[j] < -cap_rate)) and not dev.one_way:
                    new[j] = BACKWARD
                    changed = True
                if new[j] in (FORWARD, BACKWARD):
                    broke.add(j)
            # a device sliding (or a lossy gear rolling, fuzz seed 454) at zero slip must leave zero in its
            # own direction under the modes now chosen. Several break-aways in one pass change each other's loads: on fuzz seed 37 a
            # limited-slip lock broke away backward while a clutch and a bearing on its load path broke
            # away too, after which the lock's relative acceleration was forward. Kept sliding, its
            # friction would drive the motion and its event function (mode * w_rel, starting at zero)
            # would fall and never cross: a silently wrong run. It sticks again; the next pass checks
            # its holding torque against the capacity under the other devices' new modes.
            if not changed:
                w_now, a_now = self.w_rel(v), self.w_rel(a)
                a_tol = 1e-9 * max(1.0, abs_max(a))
                for j, dev in enumerate(self.devices):
                    if (new[j] in (FORWARD, BACKWARD) and abs(w_now[j]) <= scale
                            and new[j] * a_now[j] < -a_tol):
                        if j in broke and j not in tie_held:
                            if self._tie_break_holds(j, new, t, x, v, z, a, known[2]):
                                continue
                            tie_held.add(j)
                        new[j] = STUCK
                        changed = True
                    elif (not dev.coupled and new[j] in (FORWARD, BACKWARD) and old[j] in (STUCK, HELD)
                          and new[j] * w_now[j] < -scale):
                        # breaking away from rest, yet already moving against the direction its holding torque
                        # gave: its slip could not be locked at zero (``_lock_velocities``) because a motion
                        # source on its loop sets it (fuzz seed 10021); it slides the way the source drives it
                        new[j] = -new[j]
                        changed = True
                    elif new[j] == HELD and abs(a_now[j]) > a_tol:
                        # Held means that other stuck devices keep its motion at rest, so it carries no torque.
                        # A device whose relative motion accelerates is not held but dragged: its dependent row
                        # closed a loop through a motion source (a Speed source, a stuck clutch and a brake on
                        # one mass, the source's speed passing zero). It slides the way it is driven, with its
                        # kinetic torque; kept Held, it carried no torque while turning (a silently wrong run).
                        # Where its static capacity can hold the holder's kinetic torque, it sticks and the holder
                        # slides (``_stick_first``). Otherwise its speed is the source's: where the event was
                        # located past the zero (beyond round-off) its sign decides, and the slip's next zero is a
                        # new event
                        first = self._stick_first(t, x, v, z, new, j, a_tol)
                        if first is not None:
                            new[:] = first
                        elif abs(w_now[j]) > scale:
                            new[j] = FORWARD if w_now[j] > 0 else BACKWARD
                        else:
                            new[j] = FORWARD if a_now[j] > 0 else BACKWARD
                        changed = True
            if not changed and not probed:
                # a stuck device at the edge of its capacity whose load outgrows it at once: its event function
                # starts the segment at zero and falls, a crossing no solver reports (``_probe_breakaways``)
                probed = True
                for j, d in self._probe_breakaways(t, x, v, z, new, a, lam, dz, left):
                    new[j] = d
                    changed = True
            if not changed:
                break
            if 2 * k >= passes:
                changed_in += new != before
            # a holder let go: the devices it held (Held, at zero speed) hold again, and the
            # rule of _share_redundant decides among them on the next pass
            new[new == HELD] = STUCK
        else:
            raise SimulationError(self._unsettled_message(t, changed_in, passes))
        # the last pass solved the accelerations of the settled modes at (t, x, v, z): the restart reuses them
        y, yp = self._assemble_restart(t, x, v, z, new, lam, known)
        # (without lossy gears the restart holds these very v and a; with them its accelerations are solved again)
        view = self._restart_view(y, yp, None if self._coupled_rows or known is None else (v, known[0]))
        # the relief events of the modes found (a repeated run reads them as the segment's)
        self._relief = self._relief_events(t, y, yp, new, scale, view)
        return y, yp, new, scale, view

    def _still_relieved(self, new, crossed):
        """The devices whose relief event (``_relief_events``) still stands at this event: its holder is still stuck
        after the hard stops' step (``new``) and its break-away function did not cross. A device whose holder let go
        is at rest on its own and is decided like any other (fuzz seed 93099: a lossy planetary rolling Backward at
        zero speed while a hard stop held its carrier kept that mode when the stop released it, its acceleration
        -2e-10 rad/s^2 at a tie, and turned forward under its backward law)."""
        if not self._relief:
            return set()
        holder = {int(il): h for h, il in enumerate(self.c.ilam[self.offset:])}
        out = set()
        for j, il, *_ in self._relief:
            h = holder.get(int(il))
            if h is None or (new[h] == STUCK and crossed[2 * h] == 0):
                out.add(j)
        return out

    def _law(self, name, j, q, t, left):
        """``devices[j].<name>(t, left[, q_j])`` (``normal_force``, ``capacities``): for a device without inputs
        from the state (its laws depend on t and the side only) kept for the rest of this ``settle``, which asks
        them at the same instant in each of its steps (a few microseconds a call)."""
        qj = None if q is None else q[j]
        if qj is not None:
            return self._call(self.devices[j], name, qj, t, left)
        key = (name, j, t, left)
        got = self._law_memo.get(key)
        if got is None:
            got = self._law_memo[key] = self._call(self.devices[j], name, None, t, left)
        return got

    def _restart_view(self, y, yp, va=None):
        """``(w, arel, a_tol, w_max)`` of a restart state, as Python floats: the relative speeds and accelerations
        of the rows, the round-off of the accelerations (1e-9 of the largest, at least 1e-9) and the largest
        |w_rel|. The checks after the logic (``_held_sliding``, ``_check_sliding_sides``, ``_relief_events``)
        all read these; computed once per restart (a few microseconds each on a small model). ``va``: the
        restart's speeds and accelerations when the caller has them (else read from y, y')."""
        if va is None:
            _, v, a, _, _ = self.c.unpack(y, yp)
        else:
            v, a = va
        w = self.w_rel(v).tolist()
        a_tol = 1e-9 * max(1.0, abs_max(a))
        return w, self.w_rel(a).tolist(), a_tol, max(map(abs, w), default=0.0)

    def _probe_breakaways(self, t, x, v, z, modes, a, lam, dz, left):
        """``[(j, direction)]``: the stuck devices at the edge of their capacity (within ``PROBE_EDGE`` of it)
        that are beyond it a moment later, at ``t + dt`` on the state advanced by its rates (one more KKT
        solve, only when such a device exists).

        Why: the break-away function ``capacity - |load|`` of such a device starts the new segment at zero and
        falls, and neither IDA's root finding (a function zero at the start is inactive until it leaves zero)
        nor the ODE-form scan (a downward crossing) reports it: the device then holds any load. Fuzz seed 40004:
        a gearbox's unselected gear (a lossy gear, its loss proportional to its load) stuck at rest with no
        load when a DC motor's current started from zero; the ODE-form solvers kept it stuck, holding 0.24 N m
        that nothing on its idler side could react, until the shift 0.29 s later (the whole drivetrain at
        rest), while IDA broke it away on round-off. Moved by ``dt``, the load is beyond what the gear can hold,
        so it breaks away now: the crossing lies within ``dt`` of the event."""
        c = self.c
        lam_f = lam[self.offset:]
        q = self.q_from(t, x, v, z)
        edge = []
        for j, dev in enumerate(self.devices):
            if modes[j] != STUCK or j in self._stop_set:
                continue
            if dev.coupled:
                hi, lo = dev.limits(lam_f[j], lam[self.coupled[j]])
                size = max(abs(hi), abs(lo), abs(lam_f[j]), abs(lam[self.coupled[j]]), 1e-300)
                if min(hi - lam_f[j], lam_f[j] - lo) <= PROBE_EDGE * size:
                    edge.append(j)
            else:
                tau0_max = self._law("capacities", j, q, t, left)[1]
                if tau0_max - abs(lam_f[j]) <= PROBE_EDGE * max(tau0_max, 1e-300):
                    edge.append(j)
        if not edge:
            return []
        dt = PROBE_DT * max(1.0, abs(t))
        t2, x2, v2, z2 = t + dt, x + v * dt, v + a * dt, z + dz * dt
        try:
            _, lam2, _ = c.accelerations(t2, x2, v2, z2, modes)
        except StructureError:
            return []
        lam2_f = lam2[self.offset:]
        q2 = self.q_from(t2, x2, v2, z2)
        out = []
        for j in edge:
            dev = self.devices[j]
            if dev.coupled:
                d = dev.breakaway(lam2_f[j], lam2[self.coupled[j]])
            else:
                qj = None if q2 is None else q2[j]
                tau0_max = self._call(dev, "capacities", qj, t2, left)[1]
                beyond = abs(lam2_f[j]) > max(tau0_max * (1 + 1e-12), self._load_noise(x2, lam2))
                d = self._slide_direction(dev, qj, t2, left, np.sign(lam2_f[j])) if beyond else 0
            if d:
                out.append((j, d))
        return out

    def _load_noise(self, x, lam):
        """Round-off of the loads of stuck devices at positions ``x`` [m or rad] with constraint forces ``lam``:
        ``8 eps max(max_r k_r (|S_r| |x|), |lam|)`` [N or N m], ``k_r`` the start stiffness of compliant row ``r``
        and ``S_r`` its row of the relative coordinates.

        Why: a spring's force ``k (x_b - x_a - l0)`` carries the round-off of the positions it subtracts. Two masses
        at 0.7 and 0.8 m on a 100 N/m spring of length 0.1 m start with 7e-15 N of it; a brake engaging there under
        a Sine normal force (its capacity 1e-17 N at t = 2e-20 s) broke away on it, slid on a slip IDA cannot
        resolve at that scale (its speeds' noise reversed the slip at once) and stuck again, until the run was
        refused as chattering. A load that is round-off does not move a device; a real load soon exceeds it."""
        k = self.__dict__.get("_noise_rows")
        if k is None:
            from ..errors import RegmechError
            c = self.c
            try:
                stiff = np.abs(c.stiffness_estimate()) if c.Sc.shape[0] else np.zeros(0)
            except RegmechError:
                stiff = np.zeros(c.Sc.shape[0])
            k = self._noise_rows = (stiff, abs(c.Sc).tocsr())
        stiff, S = k
        pos = float((stiff * (S @ np.abs(x))).max(initial=0.0)) if stiff.size else 0.0
        return 8.0 * np.finfo(float).eps * max(pos, abs_max(lam))

    def _tie_break_holds(self, j, modes, t, x, v, z, a, dz):
        """Whether device ``j``, which broke away from rest at this event and starts sliding in ``modes`` with its
        relative acceleration against its direction, slides in its direction a moment later (``PROBE_DT``, on the
        state advanced by its rates): a break-away at a tie, kept.

        Why: a break-away is taken with the load within ``1e-9`` of the capacity when it is rising past it
        (``lam_rate``), as the root finder locates the crossing only to that. With a static capacity equal to the
        kinetic one (``peak = 1``, MSL's default) the sliding relative acceleration is then ``(load - tau0) / J_eff``:
        a load 6e-8 N m short of 80 N m on J_eff = 0.048 kg m^2 gave a_rel = +1.2e-6 rad/s^2 against a Backward
        break-away, beyond the accelerations' round-off, so the device stuck again, broke away again, and the
        logic refused the run (MSL Rotational.Examples.Friction at rtol 1e-8, t = 0.0593 s). A moment later the
        load is past the capacity and the slip leaves zero in the break-away's direction: the crossing lies within
        the probe's step. When it does not, the device stays stuck and only a load beyond the capacity moves it."""
        dt = PROBE_DT * max(1.0, abs(t))
        try:
            a2, _, _ = self.c.accelerations(t + dt, x + v * dt, v + a * dt, z + dz * dt, modes)
        except StructureError:
            return False
        return modes[j] * self.w_rel(a2)[j] > 0

    @staticmethod
    def _gear_at_tie(dev, d, sa, lam_g):
        """Whether a stuck lossy gear's loss torque ``sa`` is beyond its limit in direction ``d`` by no more than
        ``GEAR_TIE`` of its torques (round-off of the KKT solve and of IDA's algebraic variables)."""
        hi, lo = dev.limits(sa, lam_g)
        excess = sa - hi if d == FORWARD else lo - sa
        return excess <= GEAR_TIE * max(1.0, abs(sa), abs(lam_g))

    def _gear_tie_probe(self, j, dev, d, t, x, v, z, modes, a, dz):
        """The break-away of stuck lossy gear ``j`` at a tie, decided by its load a moment later (``PROBE_DT``) on the
        state advanced by its rates, in ``modes`` (the gear stuck): FORWARD/BACKWARD, or 0 to stay stuck (``d``, the
        side found at the instant, when the moment later admits no motion).

        Why: at a tie the side of the limit the solve lands on is round-off. Fuzz seed 93099: a hard stop released
        a lossy planetary's carrier with the gear's loss torque 3e-10 N m (6e-11 of it) past its backward limit and
        falling back inside; it rolled Backward at zero speed, its rolling law's acceleration -2e-10 rad/s^2, and
        then turned forward under that law, its speed function negative from the start, until the next event
        refused the run 0.21 s later (w_rel 3.9 rad/s against its mode)."""
        dt = PROBE_DT * max(1.0, abs(t))
        try:
            _, lam2, _ = self.c.accelerations(t + dt, x + v * dt, v + a * dt, z + dz * dt, modes)
        except StructureError:
            return d
        return dev.breakaway(lam2[self.offset + j], lam2[self.coupled[j]])

    def _slide_direction(self, dev, qj, t, left, sign):
        """The mode of a stuck device whose load passes its capacity in direction ``sign`` (+1 / -1): FORWARD
        (FREE for a one-way device without normal force) or BACKWARD (0, no change, for a one-way device,
        which never slides backward)."""
        if sign > 0:
            return FORWARD if (not dev.one_way or self._call(dev, "normal_force", qj, t, left) > 0) else FREE
        return 0 if dev.one_way else BACKWARD

    def _capacity_rate(self, dev, qj, t, left, tau0_max):
        """d tau0_max / dt of a device at t [N m/s], by a forward difference in time at the same state (the
        capacity moves with its normal-force signal; a command read from the state keeps its value)."""
        dt = PROBE_DT * max(1.0, abs(t))
        return (self._call(dev, "capacities", qj, t + dt, left)[1] - tau0_max) / dt

    def _held_sliding(self, view, modes, scale):
        """Whether a device slides at zero slip with no relative acceleration (held there by others) and no
        relief event: step 1 of the logic re-sticks such a device at any event, so a settled set containing
        one must be checked by a second run (``settle``). ``view``: ``_restart_view`` of the restart."""
        w, arel, a_tol, _ = view
        m = np.asarray(modes)
        ml = m.tolist()
        at_rest = [j for j, dev in enumerate(self.devices)
                   if ml[j] in (FORWARD, BACKWARD) and abs(w[j]) <= scale and abs(arel[j]) <= a_tol
                   and not dev.coupled and not dev.one_way]
        if at_rest and self._relief:
            relief = {j for j, *_ in self._relief}
            at_rest = [j for j in at_rest if j not in relief]
        if not at_rest:
            return False
        # held: its motion is fixed by the rigid rows and the stuck devices (a device that has just broken away
        # at a load equal to its kinetic torque also starts with a_rel = 0, but nothing holds it: a slip
        # controller's clutch, whose repeated run would find it stuck again at the tie)
        stuck = [int(k) for k in np.nonzero(m == STUCK)[0]]
        return any(self._fixed_by(stuck, j) for j in at_rest)

    def check_final(self, t, y, yp, modes):
        """The end of a run (``t``, its last row ``(y, y')`` in ``modes``): no device may slide, and no lossy gear
        roll, against its own direction beyond round-off (``_check_sliding_sides``).

        Why: the check at each event finds a crossing the solver did not report (an event function that started a
        segment at zero, disarmed until it rose, and fell instead) only when another event follows. Calibration
        seed 5110 cut at 0.28 s, before the fix of ``gears.gear_events``: the last segment rolled a lossy gear
        "forward" at w_a down to -0.0136 rad/s, its loss supplying power, and the run came back 7.2 % of its range
        off with an estimate of 9.6e-5. Such a run is refused, not returned."""
        v = y[self.c.iv]
        if not np.all(np.isfinite(v)):
            # a NaN speed would pass every comparison below: refused by name, never returned
            names = self.c.structure.coord_names
            bad = [names[k] for k in np.nonzero(~np.isfinite(v))[0][:4]]
            raise SimulationError(f"the run ends at t={t:.9g} with non-finite speeds of {bad}: a law or signal acting "
                                  f"on them overflows; check those components' parameters and signals")
        w = self.w_rel(v)
        self._check_sliding_sides(t, (w.tolist(), None, None, abs_max(w)), modes, 1e-9 * max(1.0, abs_max(v)))

    def _check_sliding_sides(self, t, view, modes, scale):
        """Refuse a restart with a device sliding (or a lossy gear rolling) against its own direction, or a one-way
        clutch freewheeling backward, beyond round-off.

        Its kinetic torque would then drive the motion (a friction element supplying power) and its
        event function, already past zero, would never fire: the run would go on silently wrong (fuzz
        seed 37 before the rule of step 1 above was fixed). Not reachable by the rules above; kept so
        that a gap in them is an error, never a wrong answer."""
        w, _, _, w_max = view
        limit = -max(scale, 1e-12 * w_max)
        for j, (mode, dev) in enumerate(zip(np.asarray(modes).tolist(), self.devices)):
            if mode == FREE and dev.one_way and j not in self._stop_set and w[j] < limit:
                raise SimulationError(
                    f"stick/slip logic at t={t:.9g}: one-way clutch '{dev.name}' would freewheel backward with "
                    f"w_rel = {w[j]:.6g}, which a freewheel cannot do (it locks at w_rel = 0). This is a gap in "
                    f"regmech's mode logic: please report it with the model. The other kind of solver ('ida' or "
                    f"'dop853': they find events differently) or a tighter tolerance may avoid the instant.")
            if mode not in (FORWARD, BACKWARD):
                continue
            if mode * w[j] < limit:
                raise SimulationError(
                    f"stick/slip logic at t={t:.9g}: '{dev.name}' would slide "
                    f"{'Forward' if modes[j] == FORWARD else 'Backward'} with w_rel = {w[j]:.6g}, against its own "
                    f"direction (its friction would supply power). This is a gap in regmech's mode logic: please "
                    f"report it with the model. The other kind of solver ('ida' or 'dop853': they find events "
                    f"differently) or a tighter tolerance may avoid the instant.")

    def snapshot(self):
        """The state ``settle`` leaves behind (driving sides, relief events, engagement), to ``restore`` it with
        the values of a settle that is not repeated (a run starting where an earlier one started)."""
        return (self.quadrant.copy(), list(self._relief), self.engaged.copy(), set(self._flips),
                self._stop_snapshot())

    def restore(self, snap):
        quadrant, relief, engaged, flips, stops = snap
        self._stop_restore(stops)
        self.quadrant[:] = quadrant
        self._relief = list(relief)
        self.engaged = engaged.copy()
        self._flips = set(flips)
        self._ev_key = None
        self._small_for = self._at_segment = None      # the event functions' plans belong to a segment

    def _unsettled_message(self, t, changed_in, passes):
        """The error when the iteration did not settle: names the devices whose modes kept changing in the
        second half of the passes (the others had settled), and what to change."""
        moving = [j for j in range(self.mf) if changed_in[j]] or list(range(self.mf))
        names = ", ".join(f"'{self.devices[j].name}'" for j in moving)
        return (f"stick/slip logic did not settle at t={t:.9g} s: the modes of {names} kept changing "
                f"({passes} passes; the other friction and loss devices had settled). Their laws admit no "
                f"consistent set of modes at this instant, as with two lockable devices on one rigid group "
                f"(their holding torques are not unique): put a compliance (an elastic Shaft or a "
                f"SpringDamper) between them, or check their capacities (mu, peak, normal force)")

    @staticmethod
    def _one_way_step(dev, j, old, engaged, w, lam, crossed, initial, scale, t):
        """First step of the mode logic for a one-way clutch (no Backward mode)."""
        slide = FORWARD if engaged else FREE
        if old == HELD:
            return STUCK if abs(w) <= scale else slide
        if initial:
            if w < -scale:
                raise SimulationError(
                    f"OneWayClutch '{dev.name}' starts with w_rel = {w:.6g} < 0, which a freewheel cannot "
                    f"have; give start speeds with w(flange_b) >= w(flange_a)")
            return slide if w > scale else STUCK
        if old == STUCK:
            return (FORWARD if engaged else FREE) if crossed else STUCK
        if crossed or abs(w) <= scale:
            return STUCK
        return slide

