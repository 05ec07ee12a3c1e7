"""Code shared by test files in several folders: writers of test inputs, planes, the CLI's bad-input cases."""
