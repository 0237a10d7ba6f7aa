"""Peers of regmech in the benchmarks: the same models written by hand.

``scipy_models``: First, CoupledClutches (event restarts) and the benchmark
chains by hand on ``scipy.integrate.solve_ivp``; ``casadi_models``: First and
the chains on CasADi's CVODES and IDAS (optional: ``pip install -e ".[bench]"``).
``benchmarks/bench_peers.py`` runs them interleaved with regmech.
"""
