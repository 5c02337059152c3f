"""The learned policy as a service, without ROS: what ``policy_node`` and ``episode_runner`` call.

  locate      find a checkpoint by path or by name in the installed checkpoint folders
  views       orthographic views as received, checked against the configuration a model expects
  requests    validation of service requests (embedding, phase, cluster, freshness) with reasons
  inference   PolicyModel: load + check a checkpoint, warm up, sample_mode, predict_keypose
  episodes    the sim loop's bookkeeping: episode plan, success judgement, JSONL records, summary
  retry       backoff schedule for servers that went away
"""
