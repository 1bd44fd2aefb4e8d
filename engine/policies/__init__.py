"""Policies from elsewhere: agents trained outside ACV, judged like ACV's own (issue 44 §2).

Researchers train with Stable-Baselines3, CleanRL or their own PPO on their own machines; to
give their policies a verdict, ACV runs them. Running someone else's file is the risk, so one
form is stored and run: **ONNX**, executed by onnxruntime, which interprets a graph of
operators and runs no code of the file's author. The path a policy takes:

1. :mod:`~engine.policies.onnx_check` (with the graph rules of
   :mod:`~engine.policies.onnx_rules`): the gate. The model is parsed from bytes and refused,
   each time with a message naming the rule, unless it is a small feed-forward graph of
   allow-listed operators from ``obs [N, obs_dim]`` to ``action [N, act_dim]`` for the
   experiment's env.
2. :mod:`~engine.policies.normalisation`: the optional observation normalisation, an ``.npz``
   of plain arrays (SB3 ``VecNormalize``'s mean, var, clip and epsilon).
3. :mod:`~engine.policies.onnx_policy`: the checked model as ``obs -> action mean``, one
   thread, the same callable the judges roll out for an ACV checkpoint.
4. :mod:`~engine.policies.judging` and :mod:`~engine.policies.sandbox`: the ``behaviour`` and
   ``return`` judges' rollouts in a child process with memory and time limits, cached by the
   policy's content hash.

Two converters write that one form: :mod:`~engine.policies.export` (an ACV checkpoint's
deterministic policy, so that ACV's own runs travel the same path) and
:mod:`~engine.policies.sb3` (a Stable-Baselines3 ``.zip`` read without unpickling); both build
the graph with :mod:`~engine.policies.onnx_build`.

Nothing here unpickles anything from outside: ONNX is protobuf, the normalisation is read with
``allow_pickle=False``, and an SB3 save's weights with ``torch.load(weights_only=True)``.
Modules are imported one by one (this package imports none of them), so that the judging child
loads neither torch nor the converters.
"""
