"""The benchmark's self-check for shortcuts: `run_audit(dataset)` and the report it writes.

`msvdd-bench audit DATASET` runs it; see `benchmarks.audit.core` for the probes and
`benchmarks.audit.report` for their limits.
"""

from benchmarks.audit.core import audit_key, run_audit, stored_audit
from benchmarks.audit.report import FAIL, PASS, REPORT, SKIP, AuditResult, ProbeRow, markdown, read, write

__all__ = [
    "FAIL",
    "PASS",
    "REPORT",
    "SKIP",
    "AuditResult",
    "ProbeRow",
    "audit_key",
    "markdown",
    "read",
    "run_audit",
    "stored_audit",
    "write",
]
