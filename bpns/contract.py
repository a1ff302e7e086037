"""Where ``check_environment`` lived before the workflow package; docs/NEW_TASK.md and
plugins written against it import it from here, so this name stays."""

from bpns.workflow.contract import ContractConfig, Violation, check_environment, run_checks

__all__ = ["ContractConfig", "Violation", "check_environment", "run_checks"]
