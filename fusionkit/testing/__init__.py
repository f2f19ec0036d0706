"""Helpers for plugin authors: numerical Jacobians and the factor contract suite.

    from fusionkit.testing import check_factor_contract
    check_factor_contract(MyFactorType)        # raises ContractFailure (an AssertionError)

`check_installed_factor_types()` runs it over every factor type of every installed plugin.
"""

from .contract import (ContractFailure, FactorExample, check_factor_contract, check_factor_example,
                       check_installed_factor_types)
from .jacobians import numerical_jacobians

__all__ = ["ContractFailure", "FactorExample", "check_factor_contract", "check_factor_example",
           "check_installed_factor_types", "numerical_jacobians"]
