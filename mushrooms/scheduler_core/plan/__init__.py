"""The plan as handed on: the plan document, its independent checker, exports, schema, and the not_observable answer."""
