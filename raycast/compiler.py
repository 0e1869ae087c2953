"""How Numba's compiler is run here: two of its passes copy less (`_quicker_copy_propagation`,
`_scope_copied_once`, the same machine code compiled sooner), and a watch on its lock tells a
signal handler when a compile is under way, which a signal must not cut short (`compiling`,
`after_compile`)."""
import functools
import threading

import numba.core.event


def _copy_module(deepcopy):
    """The `copy` module with ``deepcopy`` in place of its own, for one of Numba's modules to use."""
    import copy
    import types

    shim = types.ModuleType("copy")
    shim.__dict__.update(copy.__dict__)
    shim.deepcopy = deepcopy
    return shim


def _quicker_copy_propagation():
    """Copy Numba's sets of copies and aliases without ``copy.deepcopy``, to the same result.

    Numba's copy propagation and alias analysis (`numba.core.ir_utils`) copy a
    ``{label or name: set of names or (name, name)}`` with ``copy.deepcopy`` at each step of
    their fixed points: in a parallel loop's inlined body, a quarter of its compile (the merged
    walk's `cast_plain`: 7 s of 28 under ``cProfile``). ``deepcopy`` returns strings, and tuples
    of them, as they are, and rebuilds each set from a list of its members; so does this, and
    the copies iterate in the same order (``set(v)`` would not, after removals). The merged
    walk's variants compile in 9.7 s against 11.2 (`cast_plain`, one uint8 volume) and 11.4
    against 13.2 (`cast_record`), their machine code the same instruction for instruction.
    Anything else goes to ``copy.deepcopy``, and a Numba whose ``ir_utils`` does not use the
    ``copy`` module is left as it is.
    """
    import copy

    from numba.core import ir_utils

    def names(x):
        return type(x) is str or (type(x) is tuple and all(type(s) is str for s in x))

    def deepcopy(x, memo=None):
        if (type(x) is dict and memo is None
                and all(type(k) in (int, str) and type(v) is set and all(names(e) for e in v)
                        for k, v in x.items())):
            return {k: set(list(v)) for k, v in x.items()}
        return copy.deepcopy(x, memo)

    if getattr(ir_utils, "copy", None) is copy:
        ir_utils.copy = _copy_module(deepcopy)


_quicker_copy_propagation()


def _scope_copied_once():
    """Let two of Numba's passes copy a function's scope once per call, not once per piece.

    Each variable of Numba's IR holds its function's whole `ir.Scope`, so
    ``copy.deepcopy`` of one statement or block copies every variable of the
    function with it. Two passes copy IR a piece at a time:
    ``parfors.parfor.get_parfor_reductions`` each statement of a parallel
    loop that updates a variable from outside the loop, and
    ``InlineWorker.inline_ir`` (``inline="always"``) each block of the
    function it inlines. In `raycast.iso.cast_iso_image` that was a fifth of
    the compile. Within one call of either, the copies now share one copy of
    each scope, made when first needed; neither pass changes a scope between
    its copies, and the shared copy is still a copy, so what the inliner
    later does to it (renaming the callee's variables) leaves the original
    alone, as before. `cast_iso_image` compiles in 12.4 s against 15.5, and
    the test suite's 159 kernels in 846 s against 911 (two workers' sum).
    The 255 kernels that `brute` and PARC renders (with bit planes too) of
    an isosurface, a shaded translucent volume, and both lit and shadowed
    compile for uint8, int16 and float64 samples have the same machine code,
    instruction for instruction (the hashed names Numba gives string
    constants aside). A Numba whose passes are not where this looks is left
    as it is.
    """
    import copy

    from numba.core import inline_closurecall, ir
    from numba.parfors import parfor

    def copying_scopes_once(piece, shared):
        # shared.scopes: {id(scope): (scope, its copy)} while the pass runs, else None.
        def deepcopy(x, memo=None):
            scopes = getattr(shared, "scopes", None)
            if memo is None and scopes is not None and isinstance(x, piece):
                scope = x.target.scope if piece is ir.Assign else x.scope
                if isinstance(scope, ir.Scope):
                    held = scopes.get(id(scope))
                    if held is None:
                        held = scopes[id(scope)] = (scope, copy.deepcopy(scope))
                    return copy.deepcopy(x, {id(scope): held[1]})
            return copy.deepcopy(x, memo)
        return _copy_module(deepcopy)

    def sharing(run, shared, per_call):
        # The reductions pass calls itself for nested loops, under the outer call's copies;
        # each inlining gets its own, as the inliner renames variables in them afterwards.
        @functools.wraps(run)
        def wrapper(*args, **kwargs):
            outer = getattr(shared, "scopes", None)
            if outer is not None and not per_call:
                return run(*args, **kwargs)
            shared.scopes = {}
            try:
                return run(*args, **kwargs)
            finally:
                shared.scopes = outer
        return wrapper

    worker = getattr(inline_closurecall, "InlineWorker", None)
    if getattr(parfor, "copy", None) is copy and callable(getattr(parfor, "get_parfor_reductions", None)):
        reducing = threading.local()
        parfor.copy = copying_scopes_once(ir.Assign, reducing)
        parfor.get_parfor_reductions = sharing(parfor.get_parfor_reductions, reducing, per_call=False)
    if getattr(inline_closurecall, "copy", None) is copy and callable(getattr(worker, "inline_ir", None)):
        inlining = threading.local()
        inline_closurecall.copy = copying_scopes_once(ir.Block, inlining)
        worker.inline_ir = sharing(worker.inline_ir, inlining, per_call=True)


_scope_copied_once()


class _CompilerLockWatch(numba.core.event.Listener):
    """How deep Numba's compiler lock is held (compiling, or loading a kernel from the cache),
    and what is to be done once it is let go.

    A KeyboardInterrupt raised inside a compile, or in the finalizers of llvmlite's objects
    that run during one, was swallowed (the run went on and wrote its file), crashed the
    process, or left the kernel broken ("no compiled object yet"). A run's signal handler
    (`parc.stops.stop_on_signals`) therefore hands what it would raise to `after_compile` while `compiling`, and
    it is raised here, after the lock's last release, where nothing is half built.
    """

    def __init__(self):
        self.depth = 0
        self.pending = None

    def on_start(self, event):
        if threading.current_thread() is threading.main_thread():    # where signal handlers run
            self.depth += 1

    def on_end(self, event):
        if threading.current_thread() is not threading.main_thread():
            return
        self.depth -= 1
        if self.depth == 0 and self.pending is not None:
            act, self.pending = self.pending, None
            act()


_LOCK_WATCH = _CompilerLockWatch()
numba.core.event.register("numba:compiler_lock", _LOCK_WATCH)


def compiling():
    """Whether the main thread is compiling a kernel with Numba (or loading one from its cache)."""
    return _LOCK_WATCH.depth > 0


def after_compile(act):
    """Call ``act`` once the compile under way ends (it may raise); False if one is already
    waiting, which is then kept."""
    if _LOCK_WATCH.pending is not None:
        return False
    _LOCK_WATCH.pending = act
    return True
