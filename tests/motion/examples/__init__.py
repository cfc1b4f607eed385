"""Example files of formats that bring their own (see ``format_examples._own_examples``)."""
