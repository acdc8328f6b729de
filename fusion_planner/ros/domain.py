"""A DDS domain of this process's own, so that parallel runs on one machine never hear each other.

Tests and benchmarks that start nodes use it: another process's map, goal or
Path on the shared default domain would otherwise reach them (and theirs
would reach the other process). Pure standard library; no rclpy import.
"""

import fcntl
import os
import pathlib

#: Ids whose ports never collide (ROS 2 allows 0..101 on Linux).
DOMAIN_IDS = range(1, 102)

#: Lock file of the claimed id, held for the lifetime of the process.
_lock = None


#: Lock files ``{LOCK_PREFIX}_{id}.lock``: one namespace for every claiming
#: process (tests, benchmarks, other checkouts), so no two share an id.
LOCK_PREFIX = 'fusion_planner_test_domain'


def claim_private_domain():
    """Set ``ROS_DOMAIN_ID`` to an id no other claiming process on this machine holds.

    Each id has a lock file in ``$TMPDIR`` (default ``/tmp``); the first one
    this process can lock exclusively is its own until the process ends (the
    OS drops the lock then, even on a crash). Discovery is kept to this
    machine. Call before any ``rclpy.init``; node subprocesses inherit the
    environment. Idempotent.

    Returns
    -------
    int
        The domain id.

    Raises
    ------
    RuntimeError
        If every id is held by another process.
    """
    global _lock
    if _lock is None:
        lock_dir = pathlib.Path(os.environ.get('TMPDIR', '/tmp'))
        for domain in DOMAIN_IDS:
            handle = open(lock_dir / f'{LOCK_PREFIX}_{domain}.lock', 'w')
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            _lock = handle
            os.environ['ROS_DOMAIN_ID'] = str(domain)
            os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
            os.environ.pop('ROS_LOCALHOST_ONLY', None)
            break
        else:
            raise RuntimeError(f'all ROS domain ids {DOMAIN_IDS.start}..{DOMAIN_IDS.stop - 1} '
                               'are taken by other processes')
    return int(os.environ['ROS_DOMAIN_ID'])
