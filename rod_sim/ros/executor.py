"""A single-threaded rclpy executor whose wake-up costs a fraction of rclpy's.

rclpy's :class:`~rclpy.executors.SingleThreadedExecutor` gathers every entity of every node
again at each wake-up, enters each handle's context, filters each through its callback group,
builds a fresh rcl wait set and an rcl timer for the timeout, and afterwards walks every entity
to find the ready ones. For the node's ~30 entities (command subscriptions, its services and
rclpy's parameter services, timers, guard conditions, the subscriptions' QoS event handlers)
that is 0.12-0.22 ms of CPU per idle wake-up and 0.2-0.3 ms per timer callback (measured:
docs/bench.md, "The executor's wake-up"), up to half of a 2 kHz period, and each callback
wakes it twice (rclpy's handler triggers the executor's guard condition when it takes the
entity and when it is done). Here: 63-72 us idle, 90-154 us per timer callback.

:class:`LeanExecutor` keeps rclpy's semantics and its handlers (callback groups, Tasks and
coroutine callbacks, guard conditions, waitables, the shutdown and signal guard conditions,
the order in which ready entities run) and changes only how it waits:

- the entities and their handles are gathered once, and again only when a node's entity lists
  change (compared by identity: a timer destroyed and another created is a change);
- one rcl wait set sized for them is cleared and refilled per wait;
- the entity lists are compared with the cached ones only after the executor was woken
  (rclpy's nodes call :meth:`wake` whenever they create or destroy an entity) or its nodes
  changed;
- a callback group is asked once per wait whether it can run (rclpy's two group classes answer
  the same for each of their entities), not once per entity; while no entity is taken (no
  handler of it created and not yet begun), that is all the wait asks;
- the ready entities are found from the wait set's ready lists (a dict by handle pointer);
- the timeout is the wait's own (a deadline across the loop's rounds), no rcl timer;
- a subscription or timer whose callback is a plain function gets a plain handler
  (:class:`_PlainHandler`: the same steps as rclpy's Task, without the Task and its coroutine
  bookkeeping), run by ``spin_once`` as rclpy runs its Task.

Entities are created and destroyed only from the thread that spins (the node's callbacks and
its set-up), never during a wait, so the handles' use counts (rclpy's ``with handle:``) are not
taken (a waitable's ``add_to_wait_set`` takes its own). A handle found invalid when it is
added drops the cache and the wait starts again.
"""
from __future__ import annotations

import inspect
import time
from typing import Callable

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.exceptions import InvalidHandle
from rclpy.executors import ConditionReachedException, ExternalShutdownException, \
    ShutdownException, SingleThreadedExecutor, TimeoutException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.task import Task
from rclpy.utilities import timeout_sec_to_nsec
from rclpy.waitable import NumberOfEntities

_SAME_ANSWER_GROUPS = (MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup)
"""Callback group classes whose ``can_execute`` does not depend on the entity asked about."""


class _Plan:
    """The entities of the executor's nodes (each list in rclpy's order of execution) and
    what the wait set needs of them; ``key``: the identity of every entity list."""

    def __init__(self, key, nodes):
        self.key = key
        self.timers, self.subs, self.guards, self.clients, self.services = [], [], [], [], []
        self.waitables = []
        for node in nodes:
            self.waitables += [(w, node) for w in node.waitables]
            self.timers += [(t, node) for t in node.timers]
            self.subs += [(s, node) for s in node.subscriptions]
            self.guards += [(g, node) for g in node.guards]
            self.clients += [(c, node) for c in node.clients]
            self.services += [(s, node) for s in node.services]
        self.by_pointer = {}
        for kind in (self.timers, self.subs, self.clients, self.services):
            for entity, node in kind:
                self.by_pointer[entity.handle.pointer] = (entity, node)
        self.entities = [e for kind in (self.waitables, self.timers, self.subs, self.guards,
                                        self.clients, self.services) for e, _ in kind]
        self.all_runnable = None
        """(waitables, timers, subs, clients, services, guards, sizes) when every entity
        can run (the usual wait), built on first use."""
        self.wait_set = None
        self.sizes = None
        groups = {}
        for entity in self.entities:
            groups.setdefault(entity.callback_group, entity)
        self.group_members = tuple(groups.items())
        """(callback group, one of its entities) for each group of the entities."""
        self.same_answer = all(type(g) in _SAME_ANSWER_GROUPS for g in groups)
        """Whether every group answers ``can_execute`` the same for each of its entities."""

    def everything(self, extra_guards) -> tuple:
        if self.all_runnable is None:
            self.all_runnable = _select(self, lambda e: True, extra_guards)
        return self.all_runnable


def _select(plan: _Plan, runs, extra_guards) -> tuple:
    """(waitables [(w, node)], timers, subs, clients, services, guards (``extra_guards`` last),
    wait-set sizes) of the entities of ``plan`` for which ``runs(entity)``."""
    waitables = [(w, node) for w, node in plan.waitables if runs(w)]
    timers = [t for t, _ in plan.timers if runs(t)]
    subs = [s for s, _ in plan.subs if runs(s)]
    clients = [c for c, _ in plan.clients if runs(c)]
    services = [s for s, _ in plan.services if runs(s)]
    guards = [g for g, _ in plan.guards if runs(g)] + list(extra_guards)
    counts = NumberOfEntities(len(subs), len(guards), len(timers), len(clients), len(services))
    for w, _ in waitables:
        counts += w.get_num_entities()
    sizes = (counts.num_subscriptions, counts.num_guard_conditions, counts.num_timers,
             counts.num_clients, counts.num_services, counts.num_events)
    return waitables, timers, subs, clients, services, guards, sizes


class _PlainHandler:
    """What rclpy's handler Task does for a subscription or timer whose callback is a plain
    function, in one call: the callback group's ``beginning_execution``, the take, the
    callback, ``ending_execution``; an exception is kept for ``spin_once`` to raise (as a
    Task keeps it). Nothing in it can suspend (rclpy awaits a callback only when it is a
    coroutine function), so no Task, coroutine to resume or task list entry is needed; the
    entity is not marked taken: a handler that never runs (the executor's generator
    replaced) leaves its message in the wait set's next round."""

    __slots__ = ("executor", "entity", "take", "_exception")

    def __init__(self, executor, entity, take):
        self.executor, self.entity, self.take = executor, entity, take
        self._exception = None

    def __call__(self) -> None:
        executor, entity = self.executor, self.entity
        group = entity.callback_group
        if executor._is_shutdown or not group.beginning_execution(entity):
            return
        try:
            with executor._work_tracker:
                call_coroutine = self.take(entity)
                if call_coroutine is not None:
                    coroutine = call_coroutine()
                    try:
                        coroutine.send(None)
                    except StopIteration:
                        pass
                    else:
                        coroutine.close()
                        raise RuntimeError(f"the plain callback of {entity!r} suspended")
        except Exception as exc:            # rclpy's Task keeps it; spin_once raises it
            self._exception = exc
        finally:
            group.ending_execution(entity)

    def exception(self):
        return self._exception

    def result(self) -> None:
        if self._exception is not None:
            raise self._exception


def _plan_key(nodes) -> tuple:
    return tuple((node, tuple(node.subscriptions), tuple(node.timers), tuple(node.clients),
                  tuple(node.services), tuple(node.guards), tuple(node.waitables))
                 for node in nodes)


class LeanExecutor(SingleThreadedExecutor):
    """:class:`~rclpy.executors.SingleThreadedExecutor` with a cheaper wait (module docstring).
    Use it as rclpy's: ``add_node``, ``spin_once(timeout_sec)``, ``spin``, ``create_task``,
    ``spin_until_future_complete``, ``shutdown``."""

    def __init__(self, *, context=None) -> None:
        super().__init__(context=context)
        self._plan: _Plan | None = None
        self._plan_nodes: tuple = ()
        self._woken = True
        self._taken = 0
        """Entities taken: a handler made for them that has not begun (their
        ``_executor_event`` is set)."""

    def wake(self) -> None:
        """rclpy's wake-up (a node created or destroyed an entity, a future is done): the
        next wait compares the entity lists again."""
        self._woken = True
        super().wake()

    def _current_plan(self, nodes) -> _Plan:
        plan = self._plan
        nodes = tuple(nodes)
        if plan is not None and not self._woken and nodes == self._plan_nodes:
            return plan
        self._woken = False
        self._plan_nodes = nodes
        key = _plan_key(nodes)
        if plan is None or plan.key != key:
            plan = self._plan = _Plan(key, nodes)
        return plan

    def _make_handler(self, entity, node, take_from_wait_list):
        """rclpy's handler Task for ``entity``, told not to wake the executor: rclpy's
        handler triggers the executor's guard condition after taking the entity and after its
        callback, so that other threads put it back in their wait sets; a single thread
        builds its next wait after the callback in any case, and the trigger only made that
        wait return at once, empty (one wasted wait per callback)."""
        entity._executor_event = True
        self._taken += 1

        async def handler(entity, is_shutdown, work_tracker):
            if is_shutdown or not entity.callback_group.beginning_execution(entity):
                entity._executor_event = False
                self._taken -= 1
                return
            with work_tracker:
                call_coroutine = take_from_wait_list(entity)
                entity._executor_event = False
                self._taken -= 1
                try:
                    if call_coroutine is not None:
                        await call_coroutine()
                finally:
                    entity.callback_group.ending_execution(entity)
        task = Task(handler, (entity, self._is_shutdown, self._work_tracker), executor=self)
        with self._tasks_lock:
            self._tasks.append((task, entity, node))
        return task

    def _handler(self, entity, node, take):
        """The handler of a ready ``entity`` taken by ``take``: a :class:`_PlainHandler` for a
        subscription or timer with a plain callback, else rclpy's Task
        (:meth:`_make_handler`)."""
        if (take == self._take_subscription or take == self._take_timer) and \
                not inspect.iscoroutinefunction(entity.callback):
            return _PlainHandler(self, entity, take)
        return self._make_handler(entity, node, take)

    def _can_run(self, entity, groups: dict) -> bool:
        """rclpy's ``can_execute``: not taken, and its callback group can run it (``groups``
        memoises the answer of groups whose answer is the same for each of their entities)."""
        if entity._executor_event:
            return False
        group = entity.callback_group
        if type(group) not in _SAME_ANSWER_GROUPS:
            return group.can_execute(entity)
        answer = groups.get(group)
        if answer is None:
            answer = groups[group] = bool(group.can_execute(entity))
        return answer

    def _all_can_run(self, plan: _Plan, groups: dict) -> bool:
        """Whether every entity of ``plan`` can run (:meth:`_can_run` of each): with no entity
        taken and groups that answer the same for all their entities, one question per
        group."""
        if self._taken == 0 and plan.same_answer:
            return all(group.can_execute(entity) for group, entity in plan.group_members)
        return all(self._can_run(e, groups) for e in plan.entities)

    def _wait_for_ready_callbacks(self, timeout_sec=None, nodes=None,
                                  condition: Callable[[], bool] = lambda: False):
        """rclpy's generator of ready (handler, entity, node), with the cheaper wait."""
        timeout = getattr(timeout_sec, "timeout", timeout_sec)
        timeout_nsec = timeout_sec_to_nsec(timeout)
        deadline = time.monotonic_ns() + timeout_nsec if timeout_nsec > 0 else None
        yielded_work = False
        while not yielded_work and not self._is_shutdown and not condition():
            nodes_to_use = self.get_nodes() if nodes is None else nodes

            with self._tasks_lock:
                tasks = list(self._tasks)
            if tasks:
                for task, entity, node in reversed(tasks):
                    if (not task.executing() and not task.done() and
                            (node is None or node in nodes_to_use)):
                        yielded_work = True
                        yield task, entity, node
                with self._tasks_lock:
                    self._tasks = [t for t in self._tasks
                                   if not t[0].done() and not t[0].cancelled()]

            plan = self._current_plan(nodes_to_use)
            extra = (self._guard, self._sigint_gc)
            groups: dict = {}
            if self._all_can_run(plan, groups):                         # the usual wait
                waitables, timers, subs, clients, services, guards, sizes = \
                    plan.everything(extra)
            else:
                waitables, timers, subs, clients, services, guards, sizes = _select(
                    plan, lambda e: self._can_run(e, groups), extra)
            for gc in guards[:-2]:
                if gc._executor_triggered:      # triggered but not handled: again
                    gc.trigger()
            try:
                with self._context.handle:
                    wait_set = plan.wait_set
                    if wait_set is None or plan.sizes != sizes:
                        wait_set = plan.wait_set = _rclpy.WaitSet(*sizes, self._context.handle)
                        plan.sizes = sizes
                    wait_set.clear_entities()
                    for s in subs:
                        wait_set.add_subscription(s.handle)
                    for c in clients:
                        wait_set.add_client(c.handle)
                    for s in services:
                        wait_set.add_service(s.handle)
                    for t in timers:
                        wait_set.add_timer(t.handle)
                    for gc in guards:
                        wait_set.add_guard_condition(gc.handle)
                    for w, _ in waitables:
                        w.add_to_wait_set(wait_set)
                    if deadline is None:
                        wait_set.wait(timeout_nsec)     # 0: poll; < 0: until something is ready
                    else:
                        wait_set.wait(max(0, deadline - time.monotonic_ns()))
            except InvalidHandle:
                self._plan = None           # an entity went away: gather them again
                continue
            if self._is_shutdown:
                raise ShutdownException()
            if not self._context.ok():
                raise ExternalShutdownException()

            timers_ready = wait_set.get_ready_entities('timer')
            subs_ready = wait_set.get_ready_entities('subscription')
            guards_ready = set(wait_set.get_ready_entities('guard_condition'))
            clients_ready = wait_set.get_ready_entities('client')
            services_ready = wait_set.get_ready_entities('service')
            for gc in guards:       # guard conditions are taken by the wait
                if gc.handle.pointer in guards_ready:
                    gc._executor_triggered = True
            for w, node in waitables:       # while the wait set holds their state
                if w.is_ready(wait_set) and w.callback_group.can_execute(w):
                    yielded_work = True
                    yield self._make_handler(w, node, self._take_waitable), w, node

            by_pointer = plan.by_pointer
            # rclpy's order: timers, subscriptions, guard conditions, clients, services
            ready = (
                ([by_pointer[p] for p in timers_ready], self._take_timer),
                ([by_pointer[p] for p in subs_ready], self._take_subscription),
                ([(gc, node) for gc, node in plan.guards if gc._executor_triggered],
                 self._take_guard_condition),
                ([by_pointer[p] for p in clients_ready], self._take_client),
                ([by_pointer[p] for p in services_ready], self._take_service))
            for entities, take in ready:
                for entity, node in entities:
                    # rclpy's check of timers: a cancelled timer may be reported ready
                    if take == self._take_timer and not entity.handle.is_timer_ready():
                        continue
                    if entity.callback_group.can_execute(entity):
                        yielded_work = True
                        yield self._handler(entity, node, take), entity, node

            if not yielded_work and (timeout_nsec == 0 or (
                    deadline is not None and time.monotonic_ns() >= deadline)):
                raise TimeoutException()
        if self._is_shutdown:
            raise ShutdownException()
        if condition():
            raise ConditionReachedException()
