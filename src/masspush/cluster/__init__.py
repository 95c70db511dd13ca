"""Where independent work runs: this machine's processes, or a Ray cluster (`--ray ADDRESS`).

`pool` holds what the rest of the package sees (the `TaskPool` protocol, `open_pool`, the
address check) and never imports Ray; `ray_pool` and `ray_vec_env` are the only modules that
do, imported only when a run asks for a cluster (`pip install 'masspush[ray]'`).
"""
